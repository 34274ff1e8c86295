"""World: one world on a server, by id. Every method is one call (or stream) to the server."""

from .edits import Batch, EditMethods, edit_result, message_of, request as edits_request
from .errors import invalid_argument
from .frames import FrameStream, frames_request
from . import sessions, snapshots
from .snapshots import Snapshot
from .trajectories import step_trajectory
from .types import Handle, RayHit, ShapeHit, StepResult, to_vec2, vec_tuple
from .v1 import describe_pb2, edit_pb2, query_pb2, runtime_pb2, service_pb2


def _query_filter(category_bits, mask_bits):
    message = query_pb2.QueryFilter()
    if category_bits is not None:
        message.category_bits = category_bits
    if mask_bits is not None:
        message.mask_bits = mask_bits
    return message


def _shape_hits(reply):
    return [ShapeHit(Handle.from_proto(h.shape), Handle.from_proto(h.body)) for h in reply.shapes]


def _ray_hits(reply):
    return [RayHit(Handle.from_proto(h.shape), Handle.from_proto(h.body), vec_tuple(h.point),
                   vec_tuple(h.normal), h.fraction) for h in reply.hits]


class World(EditMethods):
    """A world on the server (Client.create_world, Client.world, Client.fork).

    Edit helpers (set_velocity, apply_impulse, create_body, ...) each apply at once as a batch
    of one and return an EditResult (create_* return the new Handle); `batch()` groups edits
    into one atomic call. Used as a context manager, the world is deleted at the end.
    """

    def __init__(self, client, world_id):
        self.client = client
        self.id = world_id

    def __repr__(self):
        return f"World({self.id})"

    def __eq__(self, other):
        return isinstance(other, World) and other.client is self.client and other.id == self.id

    def __hash__(self):
        return hash((id(self.client), self.id))

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, traceback):
        self.delete()
        return False

    # --- The world as a whole ---------------------------------------------------------------

    def info(self):
        """A fulcrum.v1.WorldInfo: name, tick, counts, state hash, settings, run mode,
        recording."""
        return self.client._call("GetWorld", service_pb2.GetWorldRequest(world_id=self.id))

    def describe(self):
        """A fulcrum.v1.DescribeWorldReply: every live body as a scene Body (shapes in the
        body's frame) with its handles, every joint with its anchors, the tick and state hash
        (describe.proto)."""
        return self.client._call("DescribeWorld",
                                 describe_pb2.DescribeWorldRequest(world_id=self.id))

    @property
    def tick(self):
        return self.info().tick

    @property
    def state_hash(self):
        return self.info().state_hash

    def delete(self):
        self.client._call("DeleteWorld", service_pb2.DeleteWorldRequest(world_id=self.id))

    def step(self, ticks=1, expected_tick=None, snapshot=False, timeout=None):
        """Steps `ticks` ticks (>= 1); with `expected_tick`, only if the world is at that tick
        (else FAILED_PRECONDITION). `snapshot=True` also returns the world after the last tick.
        `timeout` (s) overrides the client's per-call deadline for long steps."""
        message = service_pb2.StepRequest(world_id=self.id, ticks=_ticks(ticks),
                                          include_snapshot=bool(snapshot))
        if expected_tick is not None:
            message.expected_tick = int(expected_tick)
        reply = self.client._call("Step", message, timeout=timeout)
        taken = (Snapshot(reply.snapshot, reply.tick, reply.state_hash)
                 if reply.HasField("snapshot") else None)
        return StepResult(reply.tick, reply.state_hash, reply.awake_body_count, reply.step_ms,
                          taken)

    def trajectory(self, ticks, every=1, bodies=None, include_start=False, expected_tick=None,
                   timeout=None):
        """Steps `ticks` ticks and returns every `every`-th tick's state of `bodies` (Handles,
        (index, generation) pairs or scene indices; default every live body) as a Trajectory
        of numpy arrays, nothing skipped: the server steps only as fast as the samples are
        taken. `include_start` adds the world before the first tick. `timeout` (s): none by
        default."""
        return step_trajectory(self, _ticks(ticks), every, bodies, include_start,
                               expected_tick, timeout)

    # --- Multiplayer sessions (docs/multiplayer.md) ---------------------------------------------

    def open_session(self, max_players=0, input_delay=0, missing="none", seal="on_step",
                     max_input_lead=0):
        """Opens this world as a session (once). seal: "on_step" (ticks are sealed when the
        world steps: run() or step()) or "all_inputs" (also as soon as every present player's
        input for the next tick is in, while paused); missing: "none" or "repeat_last".
        Returns the OpenSessionReply (tick, options with defaults, the server's fingerprint)."""
        return sessions.open_session(self, max_players, input_delay, missing, seal,
                                     max_input_lead)

    def join(self, bodies=(), joints=(), name="", fingerprint=""):
        """Joins as a player owning `bodies` and `joints` (Handles, pairs or scene indices);
        returns a Player (id, secret, first_input_tick)."""
        return sessions.join(self, bodies, joints, name, fingerprint)

    def set_ownership(self, player, bodies=(), joints=()):
        """As the world's owner: gives `bodies` and `joints` (Handles, pairs or scene indices)
        to `player` (a Player or its id; 0: to no player), from whoever owned them. All of
        them or none. Returns the SetOwnershipReply (`tick`: inputs arriving from then on
        are checked against the new ownership)."""
        return sessions.set_ownership(self, player, bodies, joints)

    def send_input(self, player, tick, edits):
        """The player's input for `tick`: an EditBatch or its dict form ({"edits": [...]}),
        forces, impulses, torques and velocities on its bodies, motor speeds and targets on its
        joints. Returns the SendInputReply (`duplicate` when one was held for the tick)."""
        return sessions.send_input(self, player, tick, edits)

    def report_hash(self, player, first_tick, hashes, snapshot=None, resync=False):
        """Reports the state hashes a copy of this world reached (hashes[i] after tick
        first_tick + i; 1 to 1024 of them) as `player`. Returns the ReportHashReply: `verdict`
        MATCH, DESYNC (`divergent_tick`, `server_hash`, `client_hash`) or UNCHECKED (the ticks
        are gone from the server's window). With the copy's `snapshot` (a Snapshot or its file
        bytes) of the divergent tick, `first_difference` names the first field that differs;
        `resync` sends the player's watches a fresh start on a desync."""
        snapshot_file = None if snapshot is None else _snapshot_file(snapshot)
        return sessions.report_hash(self, player, first_tick, hashes, snapshot_file, resync)

    def watch_session(self, player=None):
        """The session's events as an iterator (SessionEvents): the start, then every confirmed
        tick. As `player`, the player is present until the iterator is closed."""
        return sessions.watch(self, player)

    # --- Edits --------------------------------------------------------------------------------

    def apply(self, batch, expected_tick=None):
        """Applies a fulcrum.v1.EditBatch (or a dict in its JSON form: {"edits": [...]}) as
        one atomic call; returns an EditResult."""
        batch = message_of(batch, edit_pb2.EditBatch, "batch")
        reply = self.client._call("ApplyEdits", edits_request(self.id, batch, expected_tick))
        return edit_result(reply)

    def batch(self, expected_tick=None):
        """`with world.batch() as b: b.set_velocity(...); b.apply_impulse(...)`: the edits
        apply together when the block ends, in one ApplyEdits call, all or none."""
        return Batch(self, expected_tick)

    def _edit(self, edit, kind):
        result = self.apply(edit_pb2.EditBatch(edits=[edit]))
        if kind == "create_body":
            return result.bodies[0]
        if kind == "create_shape":
            return result.shapes[0]
        if kind == "create_joint":
            return result.joints[0]
        return result

    # --- Frames -------------------------------------------------------------------------------

    def frames(self, every=1, quantized=False, bodies="all", until_tick=None, duration=None):
        """Frames as an iterator: `for frame in world.frames(every=1, quantized=True):`.

        every: a frame every this many ticks (the first frame comes at once).
        quantized: body states in fixed point (about a third of the bytes; positions within
            0.122 mm, angles 4.8e-5 rad, velocities 0.49 mm/s of the exact state).
        bodies: "all" (every live body in each frame), "changed" (bodies that changed since
            the reader's previous frame) or "none" (tick, hash and counts only).
        until_tick: stop after the first frame at or past this tick.
        duration: stop after this many seconds.
        """
        message = frames_request(self.id, every, bodies, quantized)
        call = self.client._stream("StreamFrames", message, timeout=duration)
        return FrameStream(call, until_tick=until_tick, duration=duration)

    def frame(self, quantized=False):
        """The world as it is now: the first frame of a stream of every body, exact by default."""
        with self.frames(bodies="all", quantized=quantized) as stream:
            return next(stream)

    def bodies(self):
        """Handles of every live body, in index order (from a frame)."""
        return [Handle(int(i), int(g)) for i, g in self.frame().handles]

    # --- Snapshots ------------------------------------------------------------------------------

    def snapshot(self):
        """The whole world now, as a Snapshot (tick, state_hash, file), received in chunks:
        any size the server holds."""
        return snapshots.download(self.client, self.id)

    def restore(self, snapshot):
        """Rolls this world back (or forward) to `snapshot` (sent in chunks); returns
        (tick, state_hash)."""
        reply = snapshots.upload(self.client, self.id, _snapshot_file(snapshot))
        return reply.tick, reply.state_hash

    def fork(self, name="fork"):
        """A new world from a snapshot of this one, with its tick and state hash."""
        return self.client.fork(self.snapshot(), name=name)

    # --- Queries --------------------------------------------------------------------------------

    def ray_cast(self, origin, translation, category_bits=None, mask_bits=None):
        """The closest hit along origin -> origin + translation (m), as a RayHit, or None."""
        hits = self._ray(origin, translation, False, category_bits, mask_bits)
        return hits[0] if hits else None

    def ray_cast_all(self, origin, translation, category_bits=None, mask_bits=None):
        """Every hit along the ray, by fraction then shape."""
        return self._ray(origin, translation, True, category_bits, mask_bits)

    def _ray(self, origin, translation, all_hits, category_bits, mask_bits):
        message = query_pb2.QueryRequest(
            world_id=self.id, filter=_query_filter(category_bits, mask_bits),
            ray_cast=query_pb2.RayCastQuery(origin=to_vec2(origin, "ray_cast.origin"),
                                            translation=to_vec2(translation,
                                                                "ray_cast.translation"),
                                            all=all_hits))
        return _ray_hits(self.client._call("Query", message))

    def overlap_aabb(self, lower, upper, category_bits=None, mask_bits=None):
        """Shapes whose bounding boxes overlap the box [lower, upper] (m), by shape id."""
        message = query_pb2.QueryRequest(
            world_id=self.id, filter=_query_filter(category_bits, mask_bits),
            aabb=query_pb2.AabbQuery(lower=to_vec2(lower, "aabb.lower"),
                                     upper=to_vec2(upper, "aabb.upper")))
        return _shape_hits(self.client._call("Query", message))

    def overlap_point(self, point, category_bits=None, mask_bits=None):
        """Shapes that contain the world point (m), by shape id."""
        message = query_pb2.QueryRequest(
            world_id=self.id, filter=_query_filter(category_bits, mask_bits),
            point=query_pb2.PointQuery(point=to_vec2(point, "point.point")))
        return _shape_hits(self.client._call("Query", message))

    # --- Real time and replays ----------------------------------------------------------------

    def run(self, max_catch_up_ticks=None):
        """Puts the world on the server's clock (a tick every dt); returns the start tick."""
        message = runtime_pb2.SetRunModeRequest(world_id=self.id,
                                                mode=runtime_pb2.RUN_MODE_REAL_TIME)
        if max_catch_up_ticks is not None:
            message.max_catch_up_ticks = max_catch_up_ticks
        return self.client._call("SetRunMode", message).tick

    def pause(self):
        """Stops the server's clock; returns the tick the world stopped at."""
        return self.client._call("SetRunMode", runtime_pb2.SetRunModeRequest(
            world_id=self.id, mode=runtime_pb2.RUN_MODE_PAUSED)).tick

    def start_recording(self, keyframe_interval=None):
        """Records the world into a replay on the server (fulcrum-server --replay-dir); returns
        the replay's name. A keyframe every `keyframe_interval` ticks (server default 60)."""
        message = runtime_pb2.StartRecordingRequest(world_id=self.id)
        if keyframe_interval is not None:
            message.keyframe_interval = keyframe_interval
        return self.client._call("StartRecording", message).name

    def stop_recording(self):
        """Closes the recording; returns (name, ticks, bytes)."""
        reply = self.client._call("StopRecording",
                                  runtime_pb2.StopRecordingRequest(world_id=self.id))
        return reply.name, reply.ticks, reply.bytes

    def download_replay(self, path=None):
        """The world's current or last recording, up to its last complete tick, as a Replay
        (saved to `path` too when given)."""
        return self.client._download(runtime_pb2.DownloadReplayRequest(world_id=self.id), path)


def _ticks(ticks):
    if isinstance(ticks, bool) or not isinstance(ticks, int) or not 1 <= ticks < 2**32:
        raise invalid_argument("ticks", f"must be a whole number >= 1 (got {ticks!r})")
    return ticks


def _snapshot_file(snapshot):
    if isinstance(snapshot, Snapshot):
        return snapshot.file
    if isinstance(snapshot, (bytes, bytearray)):
        return Snapshot.from_bytes(bytes(snapshot)).file
    raise invalid_argument("snapshot", f"expected a fulcrum.Snapshot or snapshot file bytes, "
                                       f"got {type(snapshot).__name__}")

