"""Snapshots: rollback, fork, files, damage, and a snapshot larger than gRPC's default limit."""

import grpc
import pytest

import fulcrum


def test_a_fork_continues_with_the_same_state_hash(client, scenes):
    with client.create_world(scenes / "pyramid.json") as world:
        world.step(30)  # boxes still moving: contacts and warm-start impulses are in play
        snapshot = world.snapshot()
        assert snapshot.tick == 30
        assert snapshot.state_hash == world.info().state_hash
        with client.fork(snapshot, name="copy") as fork:
            info = fork.info()
            assert (info.name, info.tick, info.state_hash) == ("copy", 30, snapshot.state_hash)
            # Bit for bit the same world: stepping both gives the same hash at every tick.
            for _ in range(3):
                assert fork.step(20).state_hash == world.step(20).state_hash


def test_a_rollback_replays_the_same_ticks(client, scenes):
    with client.create_world(scenes / "pyramid.json") as world:
        world.step(10)
        snapshot = world.snapshot()
        first = world.step(40)
        assert world.restore(snapshot) == (10, snapshot.state_hash)
        assert world.info().tick == 10
        again = world.step(40)
        assert (again.tick, again.state_hash) == (first.tick, first.state_hash)


def test_a_snapshot_file_round_trips_and_damage_is_caught(client, scenes, tmp_path):
    with client.create_world(scenes / "pyramid.json") as world:
        stepped = world.step(15, snapshot=True)  # Step's own snapshot
        taken = stepped.snapshot
        assert (taken.tick, taken.state_hash) == (15, stepped.state_hash)
        path = tmp_path / "w.snapshot"
        taken.save(path)
        loaded = fulcrum.Snapshot.load(path)
        assert (loaded.tick, loaded.state_hash) == (15, stepped.state_hash)
        records = loaded.decode()
        assert len(records.bodies) == 211 and records.tick == 15
        with world.fork() as fork:
            assert fork.info().state_hash == stepped.state_hash

        data = bytearray(path.read_bytes())
        data[len(data) // 2] ^= 0x01  # one bit in the payload
        with pytest.raises(fulcrum.FulcrumError) as error:
            fulcrum.Snapshot.from_bytes(bytes(data))
        assert error.value.code == grpc.StatusCode.DATA_LOSS
        # The server checks the envelope too: bytes that skip the client's check are refused.
        damaged = fulcrum.Snapshot(fulcrum.snapshot_pb2.SnapshotFile(), 0, 0)
        damaged.file.CopyFrom(taken.file)
        damaged.file.checksum ^= 1
        before = world.info()
        with pytest.raises(fulcrum.FulcrumError) as error:
            world.restore(damaged)
        assert error.value.code == grpc.StatusCode.DATA_LOSS
        after = world.info()
        assert (after.tick, after.state_hash) == (before.tick, before.state_hash)


def test_a_large_pyramid_snapshot_travels_in_chunks_under_default_limits(client):
    # The large pyramid (5051 bodies) once its contacts exist: 4.49 MB at tick 30 (measured),
    # over gRPC's default 4 MiB receive limit. In one GetSnapshot message a client with that
    # limit cannot take it; World.snapshot and World.restore send it in 64 KiB chunks.
    with client.create_world({"builtin": "large_pyramid"}) as world:
        world.step(30, timeout=120)
        with fulcrum.connect(client.address,
                             options=[("grpc.max_receive_message_length", 4 * 1024 * 1024),
                                      ("grpc.max_send_message_length", 4 * 1024 * 1024)]) \
                as limited:
            with pytest.raises(grpc.RpcError) as error:
                limited._stub.GetSnapshot(fulcrum.service_pb2.GetSnapshotRequest(
                    world_id=world.id), timeout=60)
            assert error.value.code() == grpc.StatusCode.RESOURCE_EXHAUSTED
            snapshot = limited.world(world.id).snapshot()
            assert snapshot.size > 4 * 1024 * 1024
            assert (snapshot.tick, snapshot.state_hash) == (30, world.info().state_hash)
            ahead = world.step(5, timeout=60)
            with limited.fork(snapshot) as fork:
                assert fork.info().state_hash == snapshot.state_hash
                assert fork.step(5, timeout=60).state_hash == ahead.state_hash
