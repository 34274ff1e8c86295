"""Replay files (proto/fulcrum/v1/replay.proto): read, check, and verify on a server.

A replay file is a sequence of records, each a varint length, a serialized ReplayRecord and the
record's FNV-1a 64 checksum (8 bytes, little endian). The first record is the header (the world
at the start); every later one is a tick: the edit batches applied before it and the state hash
after it, with a keyframe snapshot every few ticks. A file cut off mid-write reads up to its
last complete record.

Verification re-simulates the replay on a server: the header's snapshot is forked into a
temporary world, each tick's batches are applied and the world is stepped one tick, and every
state hash (and every keyframe, record by record) must equal the recording's. The server runs
the same engine as `fulcrum replay verify`, so the two agree.
"""

from typing import NamedTuple, Optional

import grpc

from .errors import FulcrumError, invalid_argument
from .snapshots import Snapshot, decode_file, fnv1a64
from .v1 import replay_pb2

FORMAT = "fulcrum.replay"
VERSION = 1


def _data_loss(message):
    return FulcrumError(grpc.StatusCode.DATA_LOSS, message)


class ReplayReport(NamedTuple):
    ok: bool
    ticks: int                 # tick records checked (all of them when ok)
    final_tick: int            # the world's tick after the last record checked
    final_hash: int            # its state hash (the recording's when ok)
    diverged_at: Optional[int] = None  # the first tick whose hash or keyframe differs
    detail: str = ""           # what differs, for people

    def __str__(self):
        if self.ok:
            return (f"OK: {self.ticks} ticks match, final tick {self.final_tick}, "
                    f"state hash {self.final_hash:016x}")
        return f"DIVERGED at tick {self.diverged_at}: {self.detail}"


class Replay:
    """A replay's records: `header` (ReplayHeader), `ticks` (ReplayTick records in order),
    `data` (the file's bytes) and `truncated` (the file ended mid-record)."""

    def __init__(self, data, header, ticks, truncated, name=""):
        self.data = data
        self.header = header
        self.ticks = ticks
        self.truncated = truncated
        self.name = name

    def __repr__(self):
        return (f"Replay({self.name or 'unnamed'}: ticks {self.start_tick}..{self.final_tick}, "
                f"{len(self.data)} bytes)")

    @property
    def initial(self):
        """The world before the first recorded tick, as a Snapshot."""
        snapshot = decode_file(self.header.initial, "replay header")
        return Snapshot(self.header.initial, snapshot.tick, snapshot.state_hash)

    @property
    def start_tick(self):
        return self.initial.tick

    @property
    def final_tick(self):
        return self.ticks[-1].tick if self.ticks else self.start_tick

    @property
    def final_hash(self):
        return self.ticks[-1].state_hash if self.ticks else self.initial.state_hash

    def save(self, path):
        with open(path, "wb") as out:
            out.write(self.data)

    @classmethod
    def load(cls, path):
        try:
            with open(path, "rb") as source:
                data = source.read()
        except OSError as error:
            raise invalid_argument("path", f"{path}: cannot read: {error.strerror}") from None
        return cls.from_bytes(data, where=str(path))

    @classmethod
    def from_bytes(cls, data, where="replay", name=""):
        """Parses and checks every record (checksum, order); raises FulcrumError (DATA_LOSS)
        naming the record and byte offset of the first damage."""
        data = bytes(data)
        header = None
        ticks = []
        pos = 0
        index = 0
        truncated = False
        while pos < len(data):
            length, p, complete = 0, pos, False
            shift = 0
            while p < len(data) and shift < 64:
                byte = data[p]
                p += 1
                length |= (byte & 0x7F) << shift
                shift += 7
                if not byte & 0x80:
                    complete = True
                    break
            if not complete or len(data) - p < length + 8:
                truncated = True
                break
            body = data[p:p + length]
            checksum = int.from_bytes(data[p + length:p + length + 8], "little")
            here = f"{where}: record {index} (byte {pos})"
            if fnv1a64(body) != checksum:
                raise _data_loss(f"{here}: checksum mismatch: the file is damaged")
            record = replay_pb2.ReplayRecord()
            try:
                record.ParseFromString(body)
            except Exception:
                raise _data_loss(f"{here}: does not parse") from None
            if header is None:
                if not record.HasField("header"):
                    raise _data_loss(f"{here}: the first record must be the header")
                header = record.header
                if header.format != FORMAT or header.version != VERSION:
                    raise _data_loss(f"{here}: a {header.format!r} version {header.version} "
                                     f"file, this client reads {FORMAT!r} version {VERSION}")
            else:
                if not record.HasField("tick"):
                    raise _data_loss(f"{here}: expected a tick record")
                ticks.append(record.tick)
            pos = p + length + 8
            index += 1
        if header is None:
            raise _data_loss(f"{where}: no header record (empty or cut off)")
        return cls(data, header, ticks, truncated, name)

    def verify(self, client):
        """Re-simulates the replay on `client`'s server; returns a ReplayReport."""
        return verify(client, self)


def verify(client, replay):
    world = client.fork(replay.initial, name="replay-verify")
    try:
        tick = replay.start_tick
        state_hash = replay.initial.state_hash
        for checked, record in enumerate(replay.ticks):
            if record.tick != tick + 1:
                return ReplayReport(False, checked, tick, state_hash, record.tick,
                                    f"record for tick {record.tick} follows tick {tick}")
            for batch in record.edits:
                world.apply(batch, expected_tick=tick)
            stepped = world.step(1, expected_tick=tick)
            tick, state_hash = stepped.tick, stepped.state_hash
            if state_hash != record.state_hash:
                return ReplayReport(False, checked, tick, state_hash, tick,
                                    f"state hash {state_hash:016x}, the recording has "
                                    f"{record.state_hash:016x}")
            if record.HasField("keyframe"):
                recorded = decode_file(record.keyframe, f"keyframe of tick {tick}")
                actual = world.snapshot().decode()
                if recorded != actual:
                    return ReplayReport(False, checked, tick, state_hash, tick,
                                        "state hash matches but the keyframe differs")
        return ReplayReport(True, len(replay.ticks), tick, state_hash)
    finally:
        world.delete()
