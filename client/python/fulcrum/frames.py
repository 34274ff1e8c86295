"""Frames (proto/fulcrum/v1/frames.proto) as Python objects with numpy arrays of body states.

A stream is lossy by design: a reader that falls behind gets the newest frame, and
`skipped_frames` says how many it missed. The package's channel options keep the frames a slow
reader gets recent (see docs/python.md, "Channel options").
"""

import threading
from typing import NamedTuple, Tuple

import grpc
import numpy as np

from .errors import FulcrumError, invalid_argument
from .types import Handle
from .v1 import frames_pb2

# Quantized steps (frames.proto, QuantizedBodyFrame): value = units * step.
POSITION_STEP = 1.0 / 4096.0            # m
ANGLE_STEP = 2.0 * np.pi / 65536.0      # rad
VELOCITY_STEP = 1.0 / 1024.0            # m/s and rad/s

BODIES = {
    "all": frames_pb2.FRAME_BODIES_ALL,
    "changed": frames_pb2.FRAME_BODIES_CHANGED,
    "none": frames_pb2.FRAME_BODIES_NONE,
}


class BodyState(NamedTuple):
    handle: Handle
    position: Tuple[float, float]         # body origin, world, m
    angle: float                          # rad
    linear_velocity: Tuple[float, float]  # of the centre of mass, m/s
    angular_velocity: float               # rad/s
    awake: bool
    exact: bool  # False: decoded from a quantized frame, within frames.proto's error bounds


class Frame:
    """One frame: the tick, the state hash, counts, and the states of the bodies it carries.

    Body states are numpy arrays in body index order, one row per body the frame carries
    (every live body with bodies="all"; the changed ones with "changed"; none with "none"):
        handles             (n, 2) int64: index, generation
        positions           (n, 2) float64: body origin, m
        angles              (n,)   float64: rad
        linear_velocities   (n, 2) float64: m/s
        angular_velocities  (n,)   float64: rad/s
        awake               (n,)   bool
        exact               (n,)   bool: False where decoded from fixed point (quantized)
    `message` is the fulcrum.v1.Frame as received.
    """

    def __init__(self, message):
        self.message = message
        self.world_id = message.world_id
        self.tick = message.tick
        self.state_hash = message.state_hash
        self.skipped_frames = message.skipped_frames
        self.skipped_ticks = message.skipped_ticks
        self.body_count = message.body_count
        self.awake_body_count = message.awake_body_count
        self.full = message.full
        self.restored = message.restored
        self.destroyed = [Handle.from_proto(h) for h in message.destroyed]
        self._decode(message)
        self._rows = None

    def _decode(self, message):
        exact = message.bodies
        quantized = message.quantized_bodies
        n = len(exact) + len(quantized)
        handles = np.empty((n, 2), dtype=np.int64)
        positions = np.empty((n, 2))
        angles = np.empty(n)
        velocities = np.empty((n, 2))
        spins = np.empty(n)
        awake = np.empty(n, dtype=bool)
        is_exact = np.empty(n, dtype=bool)
        for i, b in enumerate(exact):
            handles[i] = (b.body.index, b.body.generation)
            positions[i] = (b.position.x, b.position.y)
            angles[i] = b.angle
            velocities[i] = (b.linear_velocity.x, b.linear_velocity.y)
            spins[i] = b.angular_velocity
            awake[i] = b.awake
        is_exact[:len(exact)] = True
        if quantized:
            q = np.array([(b.index, b.generation, b.x, b.y, b.angle, b.vx, b.vy,
                           b.angular_velocity, b.awake) for b in quantized], dtype=np.int64)
            k = len(exact)
            handles[k:] = q[:, 0:2]
            positions[k:] = q[:, 2:4] * POSITION_STEP
            angles[k:] = q[:, 4] * ANGLE_STEP
            velocities[k:] = q[:, 5:7] * VELOCITY_STEP
            spins[k:] = q[:, 7] * VELOCITY_STEP
            awake[k:] = q[:, 8] != 0
            is_exact[k:] = False
        # Each body is in exactly one of the two lists, each in index order: merge them.
        order = np.argsort(handles[:, 0], kind="stable") if quantized and exact else slice(None)
        self.handles = handles[order]
        self.positions = positions[order]
        self.angles = angles[order]
        self.linear_velocities = velocities[order]
        self.angular_velocities = spins[order]
        self.awake = awake[order]
        self.exact = is_exact[order]

    def __len__(self):
        return len(self.handles)

    def __repr__(self):
        return (f"Frame(world={self.world_id}, tick={self.tick}, "
                f"state_hash={self.state_hash:016x}, bodies={len(self)}, "
                f"skipped_frames={self.skipped_frames})")

    def row(self, body):
        """The row of `body` (a Handle, an (index, generation) pair or an index) in the arrays;
        KeyError when the frame does not carry it."""
        if self._rows is None:
            self._rows = {int(index): i for i, index in enumerate(self.handles[:, 0])}
        index = body if isinstance(body, int) else body[0]
        i = self._rows[index]
        if not isinstance(body, int) and body[1] != self.handles[i, 1]:
            raise KeyError(f"body {tuple(body)}: the frame has generation {self.handles[i, 1]}")
        return i

    def body(self, body):
        """The state of one body as a BodyState."""
        i = self.row(body)
        return BodyState(
            handle=Handle(int(self.handles[i, 0]), int(self.handles[i, 1])),
            position=tuple(float(v) for v in self.positions[i]),
            angle=float(self.angles[i]),
            linear_velocity=tuple(float(v) for v in self.linear_velocities[i]),
            angular_velocity=float(self.angular_velocities[i]),
            awake=bool(self.awake[i]), exact=bool(self.exact[i]))

    def bodies(self):
        """Every body the frame carries, as BodyStates."""
        return [self.body(int(index)) for index in self.handles[:, 0]]


class FrameStream:
    """An open StreamFrames call as an iterator of Frames (World.frames).

    The first frame is the world as it is; then one arrives every `every` ticks as the world
    is stepped (by Step, or by the server's clock in real time). The stream has no end of its
    own: leave the loop (break), give `until_tick` or `duration`, or close() it; it is also a
    context manager. A stream the server ends (world deleted: NOT_FOUND; server stopping:
    UNAVAILABLE; a reader that stalled: RESOURCE_EXHAUSTED) raises FulcrumError.
    """

    def __init__(self, call, until_tick=None, duration=None):
        self._call = call
        self._until_tick = until_tick
        self._has_deadline = duration is not None
        self._closed = threading.Event()
        self._done = False

    def __iter__(self):
        return self

    def __next__(self):
        if self._done:
            raise StopIteration
        try:
            message = next(self._call)
        except StopIteration:
            self._done = True
            raise
        except grpc.RpcError as error:
            self._done = True
            if self._closed.is_set() and error.code() == grpc.StatusCode.CANCELLED:
                raise StopIteration from None
            if self._has_deadline and error.code() == grpc.StatusCode.DEADLINE_EXCEEDED:
                raise StopIteration from None
            raise FulcrumError.from_rpc(error) from None
        frame = Frame(message)
        if self._until_tick is not None and frame.tick >= self._until_tick:
            # This frame is still yielded; the next call stops.
            self.close()
            self._done = True
        return frame

    def close(self):
        """Ends the stream (the server sees the call cancelled)."""
        if not self._closed.is_set():
            self._closed.set()
            self._call.cancel()

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, traceback):
        self.close()
        return False

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass


def frames_request(world_id, every, bodies, quantized):
    if isinstance(every, bool) or not isinstance(every, int) or not 1 <= every < 2**32:
        raise invalid_argument("every_ticks",
                               f"must be a whole number in [1, 2^32) (got {every!r})")
    if bodies not in BODIES:
        raise invalid_argument("bodies", f"expected one of {sorted(BODIES)} (got {bodies!r})")
    return frames_pb2.StreamFramesRequest(world_id=world_id, every_ticks=every,
                                          bodies=BODIES[bodies], quantized=bool(quantized))
