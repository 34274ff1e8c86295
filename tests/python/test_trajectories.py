"""Lossless trajectories: every sample of the bodies named, exact, as numpy arrays."""

import grpc
import numpy as np
import pytest

import fulcrum


def test_a_trajectory_matches_frames_taken_at_the_same_ticks(client, scenes):
    with client.create_world(scenes / "pyramid.json") as world:
        traj = world.trajectory(60, every=20, bodies=[210, (3, 1)], include_start=True)
        assert list(traj.ticks) == [0, 20, 40, 60]
        assert traj.handles.tolist() == [[210, 1], [3, 1]]
        assert traj.positions.shape == (4, 2, 2)
        assert traj.angles.shape == traj.angular_velocities.shape == traj.awake.shape == (4, 2)
        assert traj.result.tick == 60
        assert int(traj.state_hashes[-1]) == traj.result.state_hash == world.info().state_hash
        # The top box falls as the pyramid settles under gravity: never above its start.
        top = traj.column(210)
        assert np.all(traj.positions[1:, top, 1] <= traj.positions[0, top, 1] + 1e-9)
        # Bit for bit the state a frame shows at the same tick.
        frame = world.frame()
        assert frame.tick == 60
        row = frame.row(fulcrum.Handle(210, 1))
        assert np.array_equal(frame.positions[row], traj.positions[-1, top])
        assert frame.angular_velocities[row] == traj.angular_velocities[-1, top]

        # No bodies named: every live body, in index order.
        everything = world.trajectory(7)
        assert everything.positions.shape == (7, 211, 2)
        assert list(everything.handles[:, 0]) == list(range(211))


def test_a_bad_trajectory_request_is_refused_and_runs_no_tick(client, scenes):
    with client.create_world(scenes / "pyramid.json") as world:
        with pytest.raises(fulcrum.FulcrumError) as error:
            world.trajectory(10, bodies=[1, 999])
        assert error.value.code == grpc.StatusCode.NOT_FOUND
        assert error.value.field == "bodies[1]"
        with pytest.raises(fulcrum.FulcrumError) as error:
            world.trajectory(10, every=0)
        assert error.value.code == grpc.StatusCode.INVALID_ARGUMENT
        assert error.value.field == "every"
        assert world.info().tick == 0
