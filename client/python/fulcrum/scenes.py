"""Scenes from dicts, JSON files and JSON text, as the server and the `fulcrum` CLI read them.

A scene is a fulcrum.v1.Scene (proto/fulcrum/v1/scene.proto). Its JSON form is the Protobuf
JSON mapping: lowerCamelCase names ("halfWidth"; the proto names, "half_width", are accepted
too), enums by name ("BODY_TYPE_DYNAMIC"), unknown fields an error. The same file works with
`fulcrum create --scene FILE`, `fulcrum sim --scene FILE` and `fulcrum.load_scene(FILE)`.
"""

import json
import os

from google.protobuf import json_format

from .errors import invalid_argument
from .v1 import scene_pb2


def scene_from_dict(data, where="scene"):
    """A Scene from a dict shaped like the scene JSON. Unknown fields are an error."""
    if not isinstance(data, dict):
        raise invalid_argument(where, f"expected a dict, got {type(data).__name__}")
    try:
        return json_format.ParseDict(data, scene_pb2.Scene())
    except json_format.ParseError as error:
        raise invalid_argument(where, str(error)) from None


def scene_from_json(text, where="scene"):
    """A Scene from JSON text."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as error:
        raise invalid_argument(where, f"not JSON: {error}") from None
    return scene_from_dict(data, where)


def load_scene(path):
    """A Scene from a JSON file (scenes/*.json, `fulcrum export` output)."""
    try:
        with open(path, encoding="utf-8") as file:
            text = file.read()
    except OSError as error:
        raise invalid_argument("scene", f"{path}: cannot read: {error.strerror}") from None
    return scene_from_json(text, where=os.fspath(path))


def to_scene(scene):
    """A Scene from a Scene, a dict, or a path (str or os.PathLike) to a JSON file."""
    if isinstance(scene, scene_pb2.Scene):
        return scene
    if isinstance(scene, dict):
        return scene_from_dict(scene)
    if isinstance(scene, (str, os.PathLike)):
        return load_scene(scene)
    raise invalid_argument(
        "scene", f"expected a fulcrum.v1.Scene, a dict or a JSON file path, "
                 f"got {type(scene).__name__}")


def scene_to_dict(scene):
    """The dict form of a Scene (the JSON a scene file holds)."""
    return json_format.MessageToDict(scene)
