"""Replays recorded on the server: download, read, verify (here and with the C++ CLI)."""

import subprocess

import grpc
import pytest

import fulcrum
from conftest import CLI_BIN


def record(client, scenes, ticks=40):
    """A pyramid recorded for `ticks` ticks with a batch of edits at tick 10."""
    world = client.create_world(scenes / "pyramid.json")
    name = world.start_recording(keyframe_interval=15)
    world.step(10)
    with world.batch() as batch:
        batch.apply_impulse(210, (0.0, 5.0))
        batch.set_velocity(1, (0.5, 0.0))
    world.step(ticks - 10)
    return world, name


def test_a_downloaded_replay_verifies_and_ends_at_the_world_state(client, scenes, tmp_path):
    world, name = record(client, scenes)
    try:
        info = world.info()
        assert world.stop_recording() == (name, 40, info.recording.bytes)
        path = tmp_path / "w.replay"
        replay = client.download_replay(name, path=path)
        assert path.read_bytes() == replay.data
        assert (replay.start_tick, replay.final_tick, len(replay.ticks)) == (0, 40, 40)
        assert replay.final_hash == info.state_hash
        assert not replay.truncated
        assert [len(t.edits) for t in replay.ticks][10] == 1  # the batch, before tick 11
        assert [t.tick for t in replay.ticks if t.HasField("keyframe")] == [15, 30]
        report = client.verify_replay(path)
        assert report.ok, report
        assert (report.ticks, report.final_tick, report.final_hash) == (40, 40, info.state_hash)
        # The engine's own verifier agrees on the file the Python client downloaded.
        out = subprocess.run([str(CLI_BIN), "replay", "verify", str(path)], capture_output=True,
                             text=True, check=False)
        assert out.returncode == 0, out.stderr
        assert f"final tick 40, state hash {info.state_hash:016x}" in out.stdout
        # The same through the world: its last recording.
        assert world.download_replay().data == replay.data
    finally:
        world.delete()


def test_verify_names_the_first_divergent_tick(client, scenes):
    world, name = record(client, scenes, ticks=20)
    world.delete()
    replay = client.download_replay(name)
    replay.ticks[12].state_hash ^= 1  # as if the recording's world had done otherwise
    report = client.verify_replay(replay)
    assert not report.ok
    assert report.diverged_at == 13 and report.ticks == 12
    assert "DIVERGED at tick 13" in str(report)
    # The edits matter: without the batch the hash differs right after it (tick 11).
    replay = client.download_replay(name)
    del replay.ticks[10].edits[:]
    report = client.verify_replay(replay)
    assert (report.ok, report.diverged_at) == (False, 11)
    # Verification leaves no world behind.
    assert "replay-verify" not in [w.name for w in client.worlds()]


def test_a_damaged_or_cut_replay_file(client, scenes):
    world, name = record(client, scenes, ticks=12)
    world.delete()
    data = client.download_replay(name).data
    cut = fulcrum.Replay.from_bytes(data[:-5])  # cut off inside the last record
    assert cut.truncated and len(cut.ticks) == 11
    assert client.verify_replay(cut).ok
    damaged = bytearray(data)
    damaged[-20] ^= 0x40
    with pytest.raises(fulcrum.FulcrumError) as error:
        fulcrum.Replay.from_bytes(bytes(damaged))
    assert error.value.code == grpc.StatusCode.DATA_LOSS
    assert "checksum mismatch" in error.value.message
    with pytest.raises(fulcrum.FulcrumError) as error:
        client.download_replay("nothing.replay")
    assert error.value.code == grpc.StatusCode.NOT_FOUND


def test_recording_needs_a_replay_dir(make_server, scenes):
    bare = make_server()
    with fulcrum.connect(bare.address) as plain:
        with plain.create_world(scenes / "pyramid.json") as world:
            with pytest.raises(fulcrum.FulcrumError) as error:
                world.start_recording()
            assert error.value.code == grpc.StatusCode.FAILED_PRECONDITION
            assert "replay-dir" in error.value.message
