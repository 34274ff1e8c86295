"""Worlds from dicts, JSON files and Scene messages; stepping; edits, batches and errors."""

import json
import math

import grpc
import numpy as np
import pytest

import fulcrum

G = 10.0
H0 = 100.0


def ball_scene(gravity=-G, height=H0, name="drop"):
    return {
        "name": name,
        "settings": {"gravity": {"x": 0, "y": gravity}, "dt": 1 / 60},
        "bodies": [{"type": "BODY_TYPE_DYNAMIC", "position": {"x": 0, "y": height},
                    "shapes": [{"circle": {"radius": 0.5}}]}],
    }


def test_dropped_ball_falls_as_the_integrator_says(client):
    with client.create_world(ball_scene()) as world:
        settings = world.info().settings
        n = 60
        world.step(n)
        y = world.frame().positions[0, 1]
    # Symplectic Euler with substeps of h = dt / s: after m = n s substeps from rest,
    # y = h0 - g h^2 m (m + 1) / 2 exactly in real arithmetic; the doubles differ from it by
    # rounding only (a few ulps of 100 m: 1e-12 is generous).
    h = settings.dt / settings.substeps
    m = n * settings.substeps
    assert y == pytest.approx(H0 - G * h * h * m * (m + 1) / 2, abs=1e-12)
    # Against free fall, h0 - g t^2 / 2, the integrator is ahead by exactly g h t / 2
    # (0.0208 m at t = 1 s with 4 substeps of 1/240 s).
    t = n * settings.dt
    assert y < H0 - G * t * t / 2
    assert abs(y - (H0 - G * t * t / 2)) == pytest.approx(G * h * t / 2, rel=1e-9)


def test_a_world_from_a_scene_file_matches_the_cli_reading(client, scenes):
    # pyramid.json: a ground and a 20-row pyramid, 1 + 210 bodies (the CLI test's figure).
    with client.create_world(scenes / "pyramid.json") as world:
        info = world.info()
        assert (info.name, info.body_count, info.tick) == ("pyramid", 211, 0)
        # The same scene as a dict and as a Scene message gives the same world, bit for bit.
        data = json.loads((scenes / "pyramid.json").read_text())
        with client.create_world(data) as from_dict, \
                client.create_world(fulcrum.load_scene(scenes / "pyramid.json")) as from_msg:
            assert from_dict.info().state_hash == info.state_hash
            assert from_msg.info().state_hash == info.state_hash
        # Scene body i is Handle(i, 1) in a new world.
        assert world.bodies() == [fulcrum.Handle(i, 1) for i in range(211)]


def test_the_name_argument_replaces_the_scene_name(client, scenes):
    with client.create_world(scenes / "pyramid.json", name="mine") as world:
        assert world.info().name == "mine"


def test_a_bad_scene_is_refused_with_its_field(client, tmp_path):
    with pytest.raises(fulcrum.FulcrumError) as error:
        client.create_world({"bodys": []})  # misspelt: refused before sending
    assert error.value.code == grpc.StatusCode.INVALID_ARGUMENT
    assert error.value.field == "scene"
    assert "bodys" in error.value.message

    bad = ball_scene()
    bad["bodies"][0]["shapes"][0]["circle"]["radius"] = -1
    before = client.stats().worlds_created
    with pytest.raises(fulcrum.FulcrumError) as error:
        client.create_world(bad)  # refused by the server, which names the field
    assert error.value.code == grpc.StatusCode.INVALID_ARGUMENT
    assert error.value.field == "scene.bodies[0].shapes[0].circle.radius"
    assert client.stats().worlds_created == before

    broken = tmp_path / "broken.json"
    broken.write_text("{ not json")
    with pytest.raises(fulcrum.FulcrumError) as error:
        client.create_world(broken)
    assert error.value.code == grpc.StatusCode.INVALID_ARGUMENT
    assert "not JSON" in error.value.message
    with pytest.raises(fulcrum.FulcrumError) as error:
        client.create_world(tmp_path / "missing.json")
    assert "cannot read" in error.value.message


def test_set_velocity_moves_a_body_in_a_straight_line(client):
    with client.create_world(ball_scene(gravity=0.0)) as world:
        result = world.set_velocity(0, (3.0, -4.0))
        assert result.tick == 0
        world.step(60)  # 1 s
        state = world.frame().body(fulcrum.Handle(0, 1))
    # No force acts, so the body moves v t: (3, -4) m in 1 s. The step adds v h per substep,
    # 240 additions of 0.0125 and -0.0166..., each rounded: 1e-12 m covers it.
    assert state.position[0] == pytest.approx(3.0, abs=1e-12)
    assert state.position[1] == pytest.approx(H0 - 4.0, abs=1e-12)
    assert state.linear_velocity == pytest.approx((3.0, -4.0), abs=1e-15)


def test_an_impulse_changes_the_velocity_by_impulse_over_mass(client):
    with client.create_world(ball_scene(gravity=0.0)) as world:
        # Circle of radius 0.5 and density 1 (the default): m = pi r^2 = 0.785 kg.
        mass = math.pi * 0.25
        world.apply_impulse(0, (2.0, 0.0))
        world.step(1)
        velocity = world.frame().linear_velocities[0]
    assert velocity == pytest.approx((2.0 / mass, 0.0), rel=1e-12)


def test_a_batch_applies_its_edits_at_one_tick_in_one_call(client):
    with client.create_world(ball_scene(gravity=0.0)) as world:
        world.step(5)
        with world.batch() as batch:
            batch.create_body({"type": "BODY_TYPE_DYNAMIC", "position": {"x": 5, "y": 0},
                               "shapes": [{"box": {"halfWidth": 0.5, "halfHeight": 0.5}}]})
            batch.create_body({"type": "BODY_TYPE_DYNAMIC", "position": {"x": -5, "y": 0},
                               "shapes": [{"circle": {"radius": 0.25}}]})
            batch.set_velocity(0, (1.0, 0.0))
            assert len(batch) == 3
        assert batch.result.tick == 5
        assert batch.result.bodies == [fulcrum.Handle(1, 1), fulcrum.Handle(2, 1)]
        info = world.info()
        assert info.body_count == 3
        assert info.state_hash == batch.result.state_hash


def test_a_batch_with_one_bad_edit_changes_nothing(client):
    with client.create_world(ball_scene(gravity=0.0)) as world:
        world.step(3)
        before = world.info()
        frame_before = world.frame()
        with pytest.raises(fulcrum.FulcrumError) as error:
            with world.batch() as batch:
                batch.set_velocity(0, (1.0, 0.0))  # fine on its own
                batch.set_transform(0, (float("nan"), 0.0))  # refused
        assert error.value.code == grpc.StatusCode.INVALID_ARGUMENT
        assert error.value.field == "batch.edits[1].set_transform.position"
        after = world.info()
        assert (after.tick, after.state_hash) == (before.tick, before.state_hash)
        # The first edit did not apply either: the body still rests.
        assert np.array_equal(world.frame().linear_velocities, frame_before.linear_velocities)


def test_an_exception_inside_a_batch_sends_nothing(client):
    with client.create_world(ball_scene(gravity=0.0)) as world:
        before = world.info().state_hash
        with pytest.raises(KeyError):
            with world.batch() as batch:
                batch.set_velocity(0, (1.0, 0.0))
                raise KeyError("the caller's own error")
        assert batch.result is None
        assert world.info().state_hash == before


def test_errors_carry_the_code_the_field_and_the_message(client):
    with client.create_world(ball_scene()) as world:
        world.step(4)
        with pytest.raises(fulcrum.FulcrumError) as error:
            world.step(1, expected_tick=2)
        assert error.value.code == grpc.StatusCode.FAILED_PRECONDITION
        assert error.value.field == "expected_tick"
        assert "the world is at tick 4, not 2" in error.value.message
        with pytest.raises(fulcrum.FulcrumError) as error:
            world.set_velocity(fulcrum.Handle(0, 7), (0, 0))  # a generation never issued
        assert error.value.code == grpc.StatusCode.NOT_FOUND
        assert error.value.field == "batch.edits[0].set_velocity"
        with pytest.raises(fulcrum.FulcrumError) as error:
            world.set_velocity(0, "fast")  # refused before sending
        assert error.value.field == "batch.edits[0].set_velocity.linear"
        with pytest.raises(fulcrum.FulcrumError) as error:
            world.step(0)
        assert (error.value.code, error.value.field) == (grpc.StatusCode.INVALID_ARGUMENT,
                                                        "ticks")
        assert world.info().tick == 4
    with pytest.raises(fulcrum.FulcrumError) as error:
        client.world(987654).step(1)
    assert error.value.code == grpc.StatusCode.NOT_FOUND
    assert error.value.field == "world_id"
    assert str(error.value) == "NOT_FOUND: world_id: no world 987654"


def test_worlds_lists_and_delete_removes(client):
    world = client.create_world(ball_scene(name="listed"))
    assert world.id in [info.world_id for info in client.worlds()]
    world.delete()
    assert world.id not in [info.world_id for info in client.worlds()]
    with pytest.raises(fulcrum.FulcrumError) as error:
        world.info()
    assert error.value.code == grpc.StatusCode.NOT_FOUND


def test_describe_lists_bodies_with_their_shapes_and_joints(client):
    scene = ball_scene()
    scene["bodies"].insert(0, {"shapes": [{"box": {"halfWidth": 5, "halfHeight": 0.5}}]})
    scene["joints"] = [{"bodyA": 0, "bodyB": 1, "localAnchorA": {"x": 0, "y": 101},
                        "distance": {"length": 1}}]
    with client.create_world(scene) as world:
        world.step(3)
        d = world.describe()
        assert (d.tick, d.state_hash) == (3, world.state_hash)
        assert [b.body.type for b in d.bodies] == [fulcrum.scene_pb2.BODY_TYPE_STATIC,
                                                   fulcrum.scene_pb2.BODY_TYPE_DYNAMIC]
        ground, ball = d.bodies
        assert [(v.x, v.y) for v in ground.body.shapes[0].polygon.vertices] == [
            (-5, -0.5), (5, -0.5), (5, 0.5), (-5, 0.5)]
        assert ball.body.shapes[0].circle.radius == 0.5
        assert len(d.joints) == 1 and d.joints[0].body_b.index == ball.handle.index
        assert (d.joints[0].local_anchor_a.x, d.joints[0].local_anchor_a.y) == (0, 101)
