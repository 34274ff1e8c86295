"""Fulcrum's Python client: worlds on a fulcrum-server, driven from Python.

    import fulcrum

    with fulcrum.connect("127.0.0.1:50051") as client:
        with client.create_world("scenes/pyramid.json") as world:
            world.step(60)
            for frame in world.frames(every=10, quantized=True, until_tick=120):
                print(frame.tick, frame.positions[-1])

See docs/python.md for the whole API and the channel options the package sets.
"""

try:
    from .v1 import service_pb2 as _check_stubs  # noqa: F401
except ImportError as _error:  # the sources without the stubs CMake generates
    raise ImportError(
        "fulcrum: the generated stubs (fulcrum.v1) are missing: build the fulcrum_python "
        "target and put build/python on PYTHONPATH, or pip install build/python "
        f"(docs/python.md) [{_error}]") from None

from .client import CHANNEL_OPTIONS, Client, connect
from .edits import Batch, attractor
from .errors import FulcrumError
from .frames import BodyState, Frame, FrameStream
from .replays import Replay, ReplayReport
from .scenes import load_scene, scene_from_dict, scene_from_json, scene_to_dict
from .sessions import Player, SessionEvents
from .snapshots import Snapshot, fnv1a64
from .trajectories import Trajectory
from .types import EditResult, Handle, RayHit, ShapeHit, StepResult
from .v1 import edit_pb2, frames_pb2, scene_pb2, service_pb2, snapshot_pb2
from .world import World

__version__ = "0.1.0"

__all__ = [
    "Batch", "BodyState", "CHANNEL_OPTIONS", "Client", "EditResult", "Frame", "FrameStream",
    "FulcrumError", "Handle", "Player", "SessionEvents", "RayHit", "Replay", "ReplayReport", "ShapeHit", "Snapshot",
    "StepResult", "Trajectory", "World", "attractor", "connect", "edit_pb2", "fnv1a64", "frames_pb2", "load_scene",
    "scene_from_dict", "scene_from_json", "scene_pb2", "scene_to_dict", "service_pb2",
    "snapshot_pb2",
]
