"""Multiplayer sessions (proto/fulcrum/v1/session.proto, docs/multiplayer.md).

A world opened as a session has players; each owns some bodies and joints and sends inputs
for ticks ahead of the world, which the server seals tick by tick and streams to every
watcher. Python clients play and watch (bots, displays, CI checks); they do not step a copy
of the world themselves, so they join without a determinism fingerprint, but they can report
the hashes a copy stepped elsewhere reached (report_hash) and learn the first tick and field
that differ.
"""

from typing import NamedTuple

import grpc

from .edits import message_of
from .errors import FulcrumError, invalid_argument
from .types import to_handle
from .v1 import edit_pb2, session_pb2

SEAL = {"on_step": session_pb2.SEAL_RULE_ON_STEP, "all_inputs": session_pb2.SEAL_RULE_ALL_INPUTS}
MISSING = {"none": session_pb2.MISSING_INPUT_NONE,
           "repeat_last": session_pb2.MISSING_INPUT_REPEAT_LAST}


class Player(NamedTuple):
    """A joined player: what SendInput and watching as the player need."""
    world_id: int
    player_id: int
    secret: str
    tick: int              # the world's tick at join
    first_input_tick: int  # the earliest tick it could send an input for at join


def open_session(world, max_players, input_delay, missing, seal, max_input_lead):
    if seal not in SEAL:
        raise invalid_argument("options.seal", f"expected one of {sorted(SEAL)} (got {seal!r})")
    if missing not in MISSING:
        raise invalid_argument("options.missing_input",
                               f"expected one of {sorted(MISSING)} (got {missing!r})")
    options = session_pb2.SessionOptions(
        max_players=int(max_players), input_delay=int(input_delay), missing_input=MISSING[missing],
        seal=SEAL[seal], max_input_lead=int(max_input_lead))
    return world.client._call("OpenSession",
                              session_pb2.OpenSessionRequest(world_id=world.id, options=options))


def join(world, bodies, joints, name, fingerprint):
    request = session_pb2.JoinSessionRequest(world_id=world.id, name=name,
                                             fingerprint=fingerprint)
    for i, body in enumerate(bodies):
        request.bodies.append(to_handle(body, f"bodies[{i}]"))
    for i, joint in enumerate(joints):
        request.joints.append(to_handle(joint, f"joints[{i}]"))
    reply = world.client._call("JoinSession", request)
    return Player(world.id, reply.player_id, reply.player_secret, reply.tick,
                  reply.first_input_tick)


def set_ownership(world, player, bodies, joints):
    player_id = player if isinstance(player, int) else getattr(player, "player_id", None)
    if not isinstance(player_id, int) or isinstance(player_id, bool) or player_id < 0:
        raise invalid_argument("player_id",
                               f"expected a Player, a player id or 0 (got {player!r})")
    request = session_pb2.SetOwnershipRequest(world_id=world.id, player_id=player_id)
    for i, body in enumerate(bodies):
        request.bodies.append(to_handle(body, f"bodies[{i}]"))
    for i, joint in enumerate(joints):
        request.joints.append(to_handle(joint, f"joints[{i}]"))
    return world.client._call("SetOwnership", request)


def send_input(world, player, tick, edits):
    batch = message_of(edits, edit_pb2.EditBatch, "input")
    request = session_pb2.SendInputRequest(world_id=world.id, player_id=player.player_id,
                                           player_secret=player.secret, tick=int(tick),
                                           input=batch)
    return world.client._call("SendInput", request)


class SessionEvents:
    """WatchSession as an iterator of fulcrum.v1.SessionEvent: the start (`event.start`: the
    world's snapshot, tick, hash, players), then every confirmed tick (`event.confirmed`), none
    skipped. Close it (or leave the `with` block) to stop; watching as a player, that is when
    the player leaves."""

    def __init__(self, call):
        self._call = call
        self._closed = False

    def __iter__(self):
        return self

    def __next__(self):
        try:
            return next(self._call)
        except grpc.RpcError as error:
            if self._closed and error.code() == grpc.StatusCode.CANCELLED:
                raise StopIteration from None
            raise FulcrumError.from_rpc(error) from None

    def close(self):
        if not self._closed:
            self._closed = True
            self._call.cancel()

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, traceback):
        self.close()
        return False


def report_hash(world, player, first_tick, hashes, snapshot_file, resync):
    if isinstance(first_tick, bool) or not isinstance(first_tick, int) or first_tick < 1:
        raise invalid_argument("first_tick", f"must be a whole number >= 1 (got {first_tick!r})")
    hashes = list(hashes)
    if not 1 <= len(hashes) <= 1024:
        raise invalid_argument("hashes", f"1 to 1024 hashes expected (got {len(hashes)})")
    for i, h in enumerate(hashes):
        if isinstance(h, bool) or not isinstance(h, int) or not 0 <= h < 2**64:
            raise invalid_argument(f"hashes[{i}]", f"must be a 64-bit unsigned hash (got {h!r})")
    request = session_pb2.ReportHashRequest(world_id=world.id, player_id=player.player_id,
                                            player_secret=player.secret, first_tick=first_tick,
                                            hashes=hashes, resync=bool(resync))
    if snapshot_file is not None:
        request.snapshot.CopyFrom(snapshot_file)
    return world.client._call("ReportHash", request)


def watch(world, player):
    request = session_pb2.WatchSessionRequest(world_id=world.id)
    if player is not None:
        request.player_id = player.player_id
        request.player_secret = player.secret
    return SessionEvents(world.client._stream("WatchSession", request))
