"""Lossless trajectories (StepTrajectory): every k-th tick of the bodies named, as numpy arrays.

Unlike frames, which a slow reader skips, a trajectory holds every sample: the server steps
only as fast as the caller takes them.
"""

import grpc
import numpy as np

from .errors import FulcrumError, invalid_argument
from .types import Handle, StepResult, to_handle
from .v1 import service_pb2


class Trajectory:
    """Samples of the bodies named, in tick order, exact to the bit.

    With S samples of B bodies (in the order the bodies were named, or index order):
        ticks               (S,)      int64
        state_hashes        (S,)      uint64: the world's state hash at each sample
        handles             (B, 2)    int64: index, generation
        positions           (S, B, 2) float64: body origin, m
        angles              (S, B)    float64: rad
        linear_velocities   (S, B, 2) float64: m/s
        angular_velocities  (S, B)    float64: rad/s
        awake               (S, B)    bool
    `result` is the StepResult after the last tick (tick, state_hash, awake_body_count,
    step_ms).
    """

    def __init__(self, samples, result):
        self.result = result
        s = len(samples)
        b = len(samples[0].bodies) if samples else 0
        self.ticks = np.fromiter((x.tick for x in samples), dtype=np.int64, count=s)
        self.state_hashes = np.fromiter((x.state_hash for x in samples), dtype=np.uint64,
                                        count=s)
        self.handles = np.array([(f.body.index, f.body.generation) for f in samples[0].bodies]
                                if samples else np.empty((0, 2)), dtype=np.int64).reshape(b, 2)
        rows = np.array([(f.position.x, f.position.y, f.angle, f.linear_velocity.x,
                          f.linear_velocity.y, f.angular_velocity, f.awake)
                         for x in samples for f in x.bodies], dtype=np.float64).reshape(s, b, 7)
        self.positions = rows[:, :, 0:2].copy()
        self.angles = rows[:, :, 2].copy()
        self.linear_velocities = rows[:, :, 3:5].copy()
        self.angular_velocities = rows[:, :, 5].copy()
        self.awake = rows[:, :, 6] != 0.0

    def __len__(self):
        return len(self.ticks)

    def __repr__(self):
        return (f"Trajectory({len(self.ticks)} samples of {len(self.handles)} bodies, "
                f"ticks {self.ticks[0] if len(self.ticks) else '-'}.."
                f"{self.ticks[-1] if len(self.ticks) else '-'})")

    def column(self, body):
        """The position of `body` (a Handle, an (index, generation) pair or an index among
        the handles) in the body axis of the arrays."""
        if isinstance(body, int) and not isinstance(body, Handle):
            matches = np.nonzero(self.handles[:, 0] == body)[0]
        else:
            h = Handle(*body)
            matches = np.nonzero((self.handles[:, 0] == h.index) &
                                 (self.handles[:, 1] == h.generation))[0]
        if len(matches) == 0:
            raise KeyError(f"body {body} is not in this trajectory")
        return int(matches[0])


def step_trajectory(world, ticks, every, bodies, include_start, expected_tick, timeout):
    if isinstance(every, bool) or not isinstance(every, int) or not 1 <= every < 2**32:
        raise invalid_argument("every", f"must be a whole number >= 1 (got {every!r})")
    message = service_pb2.StepTrajectoryRequest(
        world_id=world.id, ticks=int(ticks), every_ticks=int(every),
        include_start=bool(include_start))
    for i, body in enumerate(bodies or ()):
        message.bodies.append(to_handle(body, f"bodies[{i}]"))
    if expected_tick is not None:
        message.expected_tick = int(expected_tick)
    samples, done = [], None
    try:
        for chunk in world.client._stream("StepTrajectory", message, timeout=timeout):
            samples.extend(chunk.samples)
            if chunk.HasField("done"):
                done = chunk.done
    except grpc.RpcError as error:
        raise FulcrumError.from_rpc(error) from None
    if done is None:
        raise FulcrumError(grpc.StatusCode.DATA_LOSS,
                           "trajectory: the stream ended without the final step reply")
    return Trajectory(samples, StepResult(done.tick, done.state_hash, done.awake_body_count,
                                          done.step_ms))
