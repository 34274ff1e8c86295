"""Constant forces and attractors as edits: set_constant_force, set_attractors, attractor()."""

import math

import grpc
import pytest

import fulcrum

G = 10.0
H0 = 10.0
MASS = math.pi * 0.25  # a circle of radius 0.5 at density 1


def ball_scene(gravity=0.0, height=H0):
    return {
        "settings": {"gravity": {"x": 0, "y": gravity}, "dt": 1 / 60},
        "bodies": [{"type": "BODY_TYPE_DYNAMIC", "position": {"x": 0, "y": height},
                    "shapes": [{"circle": {"radius": 0.5}}]}],
    }


def test_a_constant_force_acts_every_tick_until_cleared(client):
    with client.create_world(ball_scene()) as world:
        world.set_constant_force(0, (2.0, 0.0), torque=0.5)
        world.step(60)
        state = world.frame().body(fulcrum.Handle(0, 1))
        # 2 N on 0.785 kg for 1 s, added every substep (240 rounded additions: 1e-12 relative
        # is generous). A one-tick apply_force would have given a sixtieth of it.
        assert state.linear_velocity[0] == pytest.approx(2.0 / MASS, rel=1e-12)
        assert state.linear_velocity[1] == 0.0
        # 0.5 N m on I = m r^2 / 2 for 1 s.
        assert state.angular_velocity == pytest.approx(0.5 / (MASS * 0.125), rel=1e-12)
        # Zeros clear it: the velocity holds from then on (no other force acts).
        world.set_constant_force(0)
        world.step(30)
        after = world.frame().body(fulcrum.Handle(0, 1))
        assert after.linear_velocity == state.linear_velocity
        assert after.angular_velocity == state.angular_velocity


def test_a_constant_force_in_a_batch_applies_with_the_other_edits(client):
    with client.create_world(ball_scene(gravity=-G)) as world:
        with world.batch() as batch:
            batch.set_velocity(0, (0.0, 0.0))
            batch.set_constant_force(0, (0.0, 5.0))
        assert len(batch.edits.edits) == 2
        assert batch.edits.edits[1].WhichOneof("kind") == "set_constant_force"
        world.step(60)
        vy = world.frame().linear_velocities[0][1]
    # Gravity and the force together: (-10 + 5 / m) m/s^2 for 1 s.
    assert vy == pytest.approx(-G + 5.0 / MASS, rel=1e-12)


def test_an_attractor_pulls_as_gravity_would_and_set_attractors_replaces_them(client):
    # A constant per-mass pull of 10 m/s^2 toward a point straight below: the same fall as
    # gravity (0, -10), to rounding.
    with client.create_world(ball_scene()) as pulled, \
            client.create_world(ball_scene(gravity=-G)) as falling:
        pulled.set_attractors([fulcrum.attractor(point=(0.0, -100.0), strength=G)])
        pulled.step(60)
        falling.step(60)
        y = pulled.frame().positions[0, 1]
        assert y == pytest.approx(falling.frame().positions[0, 1], abs=1e-12)
        assert y < H0 - 4.0
        # A dict in scene JSON form works too; an empty list removes every attractor.
        pulled.set_attractors([{"point": {"x": 0, "y": -100}, "strength": G}])
        pulled.set_attractors([])
        v = pulled.frame().linear_velocities[0]
        pulled.step(30)
        assert (pulled.frame().linear_velocities[0] == v).all()


def test_attractor_fields_and_defaults(client):
    a = fulcrum.attractor((1, 2), 100.0, falloff="inverse_square", min_distance=2.0,
                          per_mass=False, mask_bits=6)
    assert (a.point.x, a.point.y, a.strength) == (1.0, 2.0, 100.0)
    assert a.falloff == fulcrum.scene_pb2.FALLOFF_INVERSE_SQUARE
    assert (a.min_distance, a.per_mass, a.mask_bits) == (2.0, False, 6)
    # Left out: absent on the wire, so the server's defaults apply.
    b = fulcrum.attractor(strength=1.0)
    assert not b.HasField("min_distance") and not b.HasField("per_mass")
    assert not b.HasField("mask_bits")
    with pytest.raises(fulcrum.FulcrumError) as error:
        fulcrum.attractor(falloff="cubic")
    assert error.value.field == "attractor.falloff"


def test_bad_forces_and_attractors_are_refused_with_their_field(client):
    with client.create_world(ball_scene()) as world:
        before = world.state_hash
        with pytest.raises(fulcrum.FulcrumError) as error:
            world.set_constant_force(0, (math.nan, 0.0))
        assert error.value.code == grpc.StatusCode.INVALID_ARGUMENT
        assert error.value.field.startswith("batch.edits[0].set_constant_force")
        with pytest.raises(fulcrum.FulcrumError) as error:
            world.set_constant_force(0, "up")  # refused before sending
        assert error.value.field == "batch.edits[0].set_constant_force.force"
        with pytest.raises(fulcrum.FulcrumError) as error:
            world.set_attractors([{"strength": 1.0, "minDistance": -1.0}])
        assert error.value.code == grpc.StatusCode.INVALID_ARGUMENT
        assert error.value.field.startswith("batch.edits[0].set_attractors.attractors[0]")
        with pytest.raises(fulcrum.FulcrumError) as error:
            world.set_attractors([{"strenght": 1.0}])  # misspelt: refused before sending
        assert error.value.field == "batch.edits[0].set_attractors.attractors[0]"
        assert world.state_hash == before
