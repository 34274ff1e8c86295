"""Snapshots: a whole world, exactly, in a checked envelope (proto/fulcrum/v1/snapshot.proto).

Snapshot files are serialized SnapshotFile messages, the same bytes `fulcrum snapshot get --out`
writes and `fulcrum snapshot restore` reads.
"""

import grpc

from .errors import FulcrumError, invalid_argument
from .v1 import service_pb2, snapshot_pb2

FORMAT = "fulcrum.snapshot"
VERSION = 1

_FNV_OFFSET = 0xCBF29CE484222325
_FNV_PRIME = 0x100000001B3
_MASK64 = 0xFFFFFFFFFFFFFFFF


def fnv1a64(data, h=_FNV_OFFSET):
    """64-bit FNV-1a of `data` (the checksum of snapshot payloads, replay records and replay
    downloads). Pass the previous result as `h` to continue over more bytes."""
    for byte in data:
        h = ((h ^ byte) * _FNV_PRIME) & _MASK64
    return h


def _data_loss(message):
    return FulcrumError(grpc.StatusCode.DATA_LOSS, message)


class Snapshot:
    """A world at one tick: `tick`, `state_hash` and the SnapshotFile envelope (`file`).

    Restore it into the world it came from (World.restore: a rollback) or into a new world
    (Client.fork / World.fork). The server checks the envelope and the payload.
    """

    def __init__(self, file, tick, state_hash):
        self.file = file
        self.tick = tick
        self.state_hash = state_hash

    def __repr__(self):
        return (f"Snapshot(tick={self.tick}, state_hash={self.state_hash:016x}, "
                f"{len(self.file.payload)} payload bytes)")

    @property
    def size(self):
        """The envelope's encoded size, bytes."""
        return self.file.ByteSize()

    def to_bytes(self):
        return self.file.SerializeToString()

    def save(self, path):
        with open(path, "wb") as out:
            out.write(self.to_bytes())

    def decode(self):
        """The world's records (a fulcrum.v1.Snapshot: bodies, shapes, contacts, joints),
        after checking the envelope's format, version and checksum."""
        return decode_file(self.file)

    @classmethod
    def from_bytes(cls, data, where="snapshot"):
        file = snapshot_pb2.SnapshotFile()
        try:
            file.ParseFromString(data)
        except Exception:  # protobuf raises DecodeError, a subclass of Exception
            raise _data_loss(f"{where}: not a snapshot file (does not parse)") from None
        decoded = decode_file(file, where)
        return cls(file, decoded.tick, decoded.state_hash)

    @classmethod
    def load(cls, path):
        try:
            with open(path, "rb") as source:
                data = source.read()
        except OSError as error:
            raise invalid_argument("path", f"{path}: cannot read: {error.strerror}") from None
        return cls.from_bytes(data, where=str(path))


def decode_file(file, where="snapshot"):
    """The Snapshot inside a SnapshotFile, checked as the server checks it."""
    if file.format != FORMAT:
        raise FulcrumError(grpc.StatusCode.FAILED_PRECONDITION,
                           f"{where}: format is '{file.format}', expected '{FORMAT}'")
    if file.version != VERSION:
        raise FulcrumError(grpc.StatusCode.FAILED_PRECONDITION,
                           f"{where}: version {file.version}, this client reads {VERSION}")
    if fnv1a64(file.payload) != file.checksum:
        raise _data_loss(f"{where}: checksum mismatch: the payload is damaged")
    snapshot = snapshot_pb2.Snapshot()
    try:
        snapshot.ParseFromString(file.payload)
    except Exception:
        raise _data_loss(f"{where}: payload does not parse") from None
    return snapshot


# Snapshots travel in chunks (DownloadSnapshot, RestoreSnapshotStream), so that any world the
# server holds fits, whatever the message limits.
CHUNK_BYTES = 64 * 1024


def download(client, world_id):
    """The world's Snapshot, received in chunks. Offsets and sizes are checked here; the
    envelope's own checksum when it is decoded or restored."""
    parts, received = [], 0
    tick = state_hash = total = None
    last = False
    try:
        for chunk in client._stream("DownloadSnapshot",
                                    service_pb2.GetSnapshotRequest(world_id=world_id),
                                    timeout=client.timeout):
            if total is None:
                tick, state_hash, total = chunk.tick, chunk.state_hash, chunk.total_size
            if chunk.offset != received:
                raise _data_loss(f"snapshot: chunk at offset {chunk.offset}, expected {received}")
            parts.append(chunk.data)
            received += len(chunk.data)
            last = last or chunk.last
    except grpc.RpcError as error:
        raise FulcrumError.from_rpc(error) from None
    if not last or received != total:
        raise _data_loss(f"snapshot: received {received} of {total} bytes")
    file = snapshot_pb2.SnapshotFile()
    try:
        file.ParseFromString(b"".join(parts))
    except Exception:
        raise _data_loss("snapshot: the bytes received do not parse") from None
    return Snapshot(file, tick, state_hash)


def upload(client, world_id, file, name=""):
    """RestoreSnapshotStream: the SnapshotFile in chunks into world `world_id` (rollback), or
    into a new world named `name` when it is 0 (fork). Returns the RestoreSnapshotReply."""
    data = file.SerializeToString()
    checksum = fnv1a64(data)

    def messages():
        offset = 0
        while True:
            piece = data[offset:offset + CHUNK_BYTES]
            chunk = service_pb2.SnapshotChunk(offset=offset, data=piece)
            first = offset == 0
            offset += len(piece)
            if first:
                chunk.total_size = len(data)
            if offset >= len(data):
                chunk.last = True
                chunk.checksum = checksum
            yield service_pb2.RestoreSnapshotChunk(
                world_id=world_id if first else 0, name=name if first else "", chunk=chunk)
            if chunk.last:
                return

    try:
        return client._stub.RestoreSnapshotStream(messages(), timeout=client.timeout,
                                                  metadata=client._metadata)
    except grpc.RpcError as error:
        raise FulcrumError.from_rpc(error) from None
