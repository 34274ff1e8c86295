"""Edits (proto/fulcrum/v1/edit.proto) through small helpers, alone or in atomic batches.

Every helper builds one fulcrum.v1.Edit. On a World it is sent at once, as a batch of one
(one ApplyEdits call); inside `with world.batch() as batch:` the edits are collected and sent
together when the block ends, so they apply at the same tick boundary, all or none.
"""

from google.protobuf import json_format

from .errors import invalid_argument
from .types import EditResult, Handle, to_float, to_handle, to_vec2
from .v1 import edit_pb2, scene_pb2, service_pb2


def message_of(value, cls, field):
    """A message of type `cls` from itself or from a dict in its JSON form."""
    if isinstance(value, cls):
        return value
    if isinstance(value, dict):
        try:
            return json_format.ParseDict(value, cls())
        except json_format.ParseError as error:
            raise invalid_argument(field, str(error)) from None
    raise invalid_argument(field, f"expected a dict or a {cls.DESCRIPTOR.full_name}, "
                                  f"got {type(value).__name__}")


class EditMethods:
    """The edit helpers, shared by World (sends each at once) and Batch (collects them).

    Subclasses implement _edit(edit, field) -> whatever the helper returns; `field` is the
    name of the Edit's oneof member, for error messages.
    """

    def _edit(self, edit, kind):
        raise NotImplementedError

    def _where(self, kind):
        """The field path of the next edit's `kind` member, as the server would name it."""
        return f"batch.edits[0].{kind}"

    def create_body(self, body):
        """A body with its shapes and chains: a dict in scene JSON form or a fulcrum.v1.Body."""
        body = message_of(body, scene_pb2.Body, self._where("create_body"))
        return self._edit(edit_pb2.Edit(create_body=body), "create_body")

    def destroy_body(self, body):
        """Destroys the body with its shapes, contacts and joints."""
        return self._edit(edit_pb2.Edit(destroy_body=to_handle(
            body, self._where("destroy_body"))), "destroy_body")

    def create_shape(self, body, shape):
        """A shape on `body`: a dict in scene JSON form ({"circle": {"radius": 0.5}}) or a
        fulcrum.v1.Shape."""
        where = self._where("create_shape")
        return self._edit(edit_pb2.Edit(create_shape=edit_pb2.CreateShape(
            body=to_handle(body, where + ".body"),
            shape=message_of(shape, scene_pb2.Shape, where + ".shape"))), "create_shape")

    def destroy_shape(self, shape):
        return self._edit(edit_pb2.Edit(destroy_shape=to_handle(
            shape, self._where("destroy_shape"))), "destroy_shape")

    def create_joint(self, body_a, body_b, joint):
        """A joint between two bodies: a dict in scene JSON form ({"revolute": {}},
        "localAnchorA": ...) or a fulcrum.v1.Joint; its bodyA/bodyB indices are ignored."""
        where = self._where("create_joint")
        return self._edit(edit_pb2.Edit(create_joint=edit_pb2.CreateJoint(
            body_a=to_handle(body_a, where + ".body_a"),
            body_b=to_handle(body_b, where + ".body_b"),
            joint=message_of(joint, scene_pb2.Joint, where + ".joint"))), "create_joint")

    def destroy_joint(self, joint):
        return self._edit(edit_pb2.Edit(destroy_joint=to_handle(
            joint, self._where("destroy_joint"))), "destroy_joint")

    def set_transform(self, body, position, angle=0.0):
        """Moves the body's origin to `position` (m) at `angle` (rad)."""
        where = self._where("set_transform")
        return self._edit(edit_pb2.Edit(set_transform=edit_pb2.SetTransform(
            body=to_handle(body, where + ".body"), position=to_vec2(position, where + ".position"),
            angle=to_float(angle, where + ".angle"))), "set_transform")

    def set_velocity(self, body, linear, angular=0.0):
        """Sets the centre of mass's velocity (m/s) and the angular velocity (rad/s)."""
        where = self._where("set_velocity")
        return self._edit(edit_pb2.Edit(set_velocity=edit_pb2.SetVelocity(
            body=to_handle(body, where + ".body"), linear=to_vec2(linear, where + ".linear"),
            angular=to_float(angular, where + ".angular"))), "set_velocity")

    def apply_force(self, body, force, point=None):
        """A force (N) for the next tick only, at a world point (m; None: the centre of mass)."""
        where = self._where("apply_force")
        message = edit_pb2.ApplyForce(body=to_handle(body, where + ".body"),
                                      force=to_vec2(force, where + ".force"))
        if point is not None:
            message.point.CopyFrom(to_vec2(point, where + ".point"))
        return self._edit(edit_pb2.Edit(apply_force=message), "apply_force")

    def apply_impulse(self, body, impulse, point=None, angular_impulse=0.0):
        """A linear impulse (N s) at a world point (None: the centre of mass), plus an angular
        impulse (N m s)."""
        where = self._where("apply_impulse")
        message = edit_pb2.ApplyImpulse(
            body=to_handle(body, where + ".body"), impulse=to_vec2(impulse, where + ".impulse"),
            angular_impulse=to_float(angular_impulse, where + ".angular_impulse"))
        if point is not None:
            message.point.CopyFrom(to_vec2(point, where + ".point"))
        return self._edit(edit_pb2.Edit(apply_impulse=message), "apply_impulse")

    def apply_torque(self, body, torque):
        """A torque (N m) for the next tick only."""
        where = self._where("apply_torque")
        return self._edit(edit_pb2.Edit(apply_torque=edit_pb2.ApplyTorque(
            body=to_handle(body, where + ".body"), torque=to_float(torque, where + ".torque"))),
            "apply_torque")

    def set_material(self, shape, friction, restitution):
        where = self._where("set_material")
        return self._edit(edit_pb2.Edit(set_material=edit_pb2.SetMaterial(
            shape=to_handle(shape, where + ".shape"),
            friction=to_float(friction, where + ".friction"),
            restitution=to_float(restitution, where + ".restitution"))), "set_material")

    def set_filter(self, shape, category_bits=1, mask_bits=0xFFFFFFFFFFFFFFFF, group_index=0):
        """Which shapes `shape` collides with (scene.proto Filter)."""
        where = self._where("set_filter")
        return self._edit(edit_pb2.Edit(set_filter=edit_pb2.SetFilter(
            shape=to_handle(shape, where + ".shape"),
            filter=scene_pb2.Filter(category_bits=category_bits, mask_bits=mask_bits,
                                    group_index=group_index))), "set_filter")

    def set_motor(self, joint, speed):
        """The joint motor's speed, rad/s (prismatic: m/s)."""
        where = self._where("set_motor")
        return self._edit(edit_pb2.Edit(set_motor=edit_pb2.SetMotor(
            joint=to_handle(joint, where + ".joint"), speed=to_float(speed, where + ".speed"))),
            "set_motor")

    def set_joint_target(self, joint, target):
        """A target joint's world point, m."""
        where = self._where("set_joint_target")
        return self._edit(edit_pb2.Edit(set_joint_target=edit_pb2.SetJointTarget(
            joint=to_handle(joint, where + ".joint"), target=to_vec2(target, where + ".target"))),
            "set_joint_target")

    def set_gravity(self, gravity):
        """World gravity, m/s^2."""
        return self._edit(edit_pb2.Edit(set_gravity=to_vec2(
            gravity, self._where("set_gravity"))), "set_gravity")

    def set_settings(self, settings):
        """World settings: a dict in scene JSON form ({"substeps": 8}) or a
        fulcrum.v1.WorldSettings; present fields replace the current values."""
        settings = message_of(settings, scene_pb2.WorldSettings, self._where("set_settings"))
        return self._edit(edit_pb2.Edit(set_settings=settings), "set_settings")

    def set_constant_force(self, body, force=(0.0, 0.0), torque=0.0):
        """A force (N) at the centre of mass and a torque (N m) acting every tick from the next
        on, until set again; replaces the body's previous ones (zeros: none)."""
        where = self._where("set_constant_force")
        return self._edit(edit_pb2.Edit(set_constant_force=edit_pb2.SetConstantForce(
            body=to_handle(body, where + ".body"), force=to_vec2(force, where + ".force"),
            torque=to_float(torque, where + ".torque"))), "set_constant_force")

    def set_attractors(self, attractors=()):
        """Replaces the world's attractors as a whole (empty: none). Each is a dict in scene
        JSON form, a fulcrum.v1.Attractor or one made by fulcrum.attractor()."""
        where = self._where("set_attractors")
        message = edit_pb2.SetAttractors()
        for i, a in enumerate(attractors):
            message.attractors.append(
                message_of(a, scene_pb2.Attractor, f"{where}.attractors[{i}]"))
        return self._edit(edit_pb2.Edit(set_attractors=message), "set_attractors")

    def set_awake(self, body, awake=True):
        where = self._where("set_awake")
        return self._edit(edit_pb2.Edit(set_awake=edit_pb2.SetAwake(
            body=to_handle(body, where + ".body"), awake=bool(awake))), "set_awake")


_FALLOFFS = {"constant": scene_pb2.FALLOFF_CONSTANT,
             "inverse_square": scene_pb2.FALLOFF_INVERSE_SQUARE}


def attractor(point=(0.0, 0.0), strength=0.0, falloff="constant", min_distance=None,
              per_mass=None, mask_bits=None):
    """A fulcrum.v1.Attractor (scene.proto): a pull toward `point` (m; a push for negative
    strength) on every dynamic body whose shapes' category bits meet `mask_bits`. `strength` is
    an acceleration (m/s^2) when `per_mass` (the server's default), else a force (N); with
    falloff "inverse_square" it is the pull at 1 m. Inside `min_distance` (m; the server's
    default 0.5) the pull falls linearly to zero at the point. Arguments left None take the
    server's defaults."""
    field = "attractor"
    if falloff not in _FALLOFFS:
        raise invalid_argument(field + ".falloff",
                               f"expected one of {sorted(_FALLOFFS)}, got {falloff!r}")
    message = scene_pb2.Attractor(point=to_vec2(point, field + ".point"),
                                  strength=to_float(strength, field + ".strength"),
                                  falloff=_FALLOFFS[falloff])
    if min_distance is not None:
        message.min_distance = to_float(min_distance, field + ".min_distance")
    if per_mass is not None:
        message.per_mass = bool(per_mass)
    if mask_bits is not None:
        message.mask_bits = int(mask_bits)
    return message


def edit_result(reply):
    """An EditResult from an ApplyEditsReply."""
    return EditResult(
        tick=reply.tick, state_hash=reply.state_hash,
        bodies=[Handle.from_proto(h) for h in reply.bodies],
        shapes=[Handle.from_proto(h) for h in reply.shapes],
        joints=[Handle.from_proto(h) for h in reply.joints])


class Batch(EditMethods):
    """Edits collected by `with world.batch() as batch:` and applied as one atomic ApplyEdits
    when the block ends without an exception (an exception discards them, nothing is sent).

    The helpers return None; handles of created objects are in `batch.result` (an EditResult:
    bodies, shapes and joints in edit order) after the block. A refused batch raises
    FulcrumError and changes nothing.
    """

    def __init__(self, world, expected_tick=None):
        self._world = world
        self._expected_tick = expected_tick
        self.edits = edit_pb2.EditBatch()
        self.result = None

    def __len__(self):
        return len(self.edits.edits)

    def _where(self, kind):
        return f"batch.edits[{len(self.edits.edits)}].{kind}"

    def _edit(self, edit, kind):
        self.edits.edits.append(edit)

    def apply(self):
        """Sends the edits collected so far as one batch (done by the `with` block's end)."""
        self.result = self._world.apply(self.edits, expected_tick=self._expected_tick)
        return self.result

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, traceback):
        if exc_type is None:
            self.apply()
        return False


def request(world_id, batch, expected_tick=None):
    """An ApplyEditsRequest."""
    message = service_pb2.ApplyEditsRequest(world_id=world_id, batch=batch)
    if expected_tick is not None:
        message.expected_tick = int(expected_tick)
    return message
