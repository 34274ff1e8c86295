"""Plain values the API hands out and takes: handles, vectors, query hits, step results."""

from typing import NamedTuple, Optional, Tuple

from .errors import invalid_argument
from .v1 import scene_pb2, snapshot_pb2


class Handle(NamedTuple):
    """A body, shape or joint: {index, generation}, as on the wire (snapshot.proto Handle).

    A stale handle (its object destroyed) is refused by the server with NOT_FOUND, never
    taken for another object. In a world just created from a scene, scene body i is
    Handle(i, 1): bodies are numbered in the order the scene assembles them (builtin,
    builders, explicit bodies).
    """

    index: int
    generation: int = 1

    def to_proto(self):
        return snapshot_pb2.Handle(index=self.index, generation=self.generation)

    @classmethod
    def from_proto(cls, message):
        return cls(message.index, message.generation)


class RayHit(NamedTuple):
    shape: Handle
    body: Handle
    point: Tuple[float, float]   # world, m
    normal: Tuple[float, float]  # world unit surface normal
    fraction: float              # along the translation, [0, 1]


class ShapeHit(NamedTuple):
    shape: Handle
    body: Handle


class StepResult(NamedTuple):
    tick: int              # the world's tick after stepping
    state_hash: int        # at `tick`
    awake_body_count: int  # at `tick`
    step_ms: float         # server wall time of the steps, ms (not deterministic)
    snapshot: Optional["object"] = None  # a fulcrum.Snapshot when asked for


class EditResult(NamedTuple):
    tick: int          # the tick boundary the batch applied at
    state_hash: int    # after the batch
    bodies: list       # Handles created by the batch, in edit order
    shapes: list
    joints: list


def to_handle(value, field):
    """A Handle proto from a Handle, an (index, generation) pair, an int index (generation 1)
    or a Handle proto."""
    if isinstance(value, snapshot_pb2.Handle):
        return value
    if isinstance(value, bool):
        raise invalid_argument(field, f"expected a handle, got {value!r}")
    if isinstance(value, int):
        return snapshot_pb2.Handle(index=value, generation=1)
    try:
        index, generation = value
        return snapshot_pb2.Handle(index=int(index), generation=int(generation))
    except (TypeError, ValueError):
        raise invalid_argument(
            field, f"expected a handle (index, generation) or an index, got {value!r}") from None


def to_vec2(value, field):
    """A Vec2 proto from any pair of numbers (tuple, list, numpy array, Vec2). Ranges and
    finiteness are the server's to check: its message names the edit's place in the batch."""
    if isinstance(value, scene_pb2.Vec2):
        return value
    try:
        x, y = (float(v) for v in value)
    except (TypeError, ValueError):
        raise invalid_argument(field, f"expected two numbers (x, y), got {value!r}") from None
    return scene_pb2.Vec2(x=x, y=y)


def to_float(value, field):
    try:
        return float(value)
    except (TypeError, ValueError):
        raise invalid_argument(field, f"expected a number, got {value!r}") from None


def vec_tuple(message):
    return (message.x, message.y)
