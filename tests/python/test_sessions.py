"""Multiplayer sessions from Python: two players take turns, a spectator sees every confirmed
tick with each player's input, a player cannot push another player's body, and reported hashes
are checked against the server's."""

import grpc
import pytest

import fulcrum
from fulcrum.v1 import session_pb2

TOP, BELOW = 210, 209  # the pyramid's top two boxes (scene indices)


def push(body, x):
    return {"edits": [{"applyImpulse": {"body": {"index": body, "generation": 1},
                                        "impulse": {"x": x, "y": 0}}}]}


def test_two_players_take_turns_and_a_spectator_sees_every_tick(client, scenes):
    with client.create_world(scenes / "pyramid.json") as world:
        opened = world.open_session(max_players=2, seal="all_inputs")
        assert opened.options.max_players == 2 and opened.tick == 0
        one = world.join(bodies=[TOP], name="one")
        two = world.join(bodies=[BELOW], name="two")
        assert (one.player_id, two.player_id) == (1, 2)
        with world.watch_session() as events:
            start = next(events)
            assert start.HasField("start") and start.start.tick == 0
            assert [p.name for p in start.start.players] == ["one", "two"]
            for tick in range(10):
                world.send_input(one, tick, push(TOP, 1.0) if tick % 3 == 0 else {})
                assert world.tick == tick, "the turn waits for player two"
                assert not world.send_input(two, tick, push(BELOW, -1.0)).duplicate
                assert world.tick == tick + 1
            confirmed = [next(events).confirmed for _ in range(10)]
        assert [c.tick.tick for c in confirmed] == list(range(1, 11))
        # Player one pushed at ticks 0, 3, 6 and 9; player two every tick; in player order.
        assert list(confirmed[0].batch_players) == [1, 2]
        assert list(confirmed[1].batch_players) == [2]
        assert confirmed[-1].tick.state_hash == world.info().state_hash


def test_a_player_cannot_push_another_players_body(client, scenes):
    with client.create_world(scenes / "pyramid.json") as world:
        world.open_session()
        one = world.join(bodies=[TOP])
        world.join(bodies=[BELOW])
        with pytest.raises(fulcrum.FulcrumError) as error:
            world.send_input(one, 1, push(BELOW, 1.0))
        assert error.value.code == grpc.StatusCode.PERMISSION_DENIED
        assert error.value.field == "input.edits[0].apply_impulse.body"
        with pytest.raises(fulcrum.FulcrumError) as error:
            world.open_session(seal="sometimes")
        assert error.value.field == "options.seal"


def test_reported_hashes_match_and_a_wrong_one_is_named_by_its_tick(client, scenes):
    with client.create_world(scenes / "pyramid.json") as world:
        world.open_session(max_players=1, seal="all_inputs")
        one = world.join(bodies=[TOP])
        with world.watch_session() as events:
            next(events)
            for tick in range(6):
                world.send_input(one, tick, push(TOP, 0.5))
            hashes = [next(events).confirmed.tick.state_hash for _ in range(6)]
        HashVerdict = session_pb2.HashVerdict
        reply = world.report_hash(one, 1, hashes)
        assert reply.verdict == HashVerdict.HASH_VERDICT_MATCH
        assert (reply.checked_from, reply.checked_through) == (1, 6)
        wrong = list(hashes)
        wrong[2] ^= 1  # the hash after tick 3
        reply = world.report_hash(one, 1, wrong)
        assert reply.verdict == HashVerdict.HASH_VERDICT_DESYNC
        assert reply.divergent_tick == 3
        assert (reply.server_hash, reply.client_hash) == (hashes[2], wrong[2])
        # With the copy's snapshot of the divergent tick (here the server's own world at tick 6,
        # so nothing differs), the reply compares the two.
        reply = world.report_hash(one, 6, [hashes[5] ^ 1], snapshot=world.snapshot())
        assert reply.verdict == HashVerdict.HASH_VERDICT_DESYNC and reply.divergent_tick == 6
        assert reply.first_difference == ""
        with pytest.raises(fulcrum.FulcrumError) as error:
            world.report_hash(one, 1, [2**64])
        assert error.value.field == "hashes[0]"
        with pytest.raises(fulcrum.FulcrumError) as error:
            world.report_hash(one, 0, hashes)
        assert error.value.field == "first_tick"


def test_the_owner_gives_a_body_to_another_player_and_takes_it_back(client, scenes):
    with client.create_world(scenes / "pyramid.json") as world:
        world.open_session()
        one = world.join(bodies=[TOP])
        two = world.join()
        reply = world.set_ownership(two, bodies=[TOP])
        assert reply.tick == world.tick
        world.send_input(two, 1, push(TOP, 1.0))
        with pytest.raises(fulcrum.FulcrumError) as error:
            world.send_input(one, 1, push(TOP, 1.0))
        assert error.value.code == grpc.StatusCode.PERMISSION_DENIED
        world.set_ownership(0, bodies=[TOP])
        with pytest.raises(fulcrum.FulcrumError) as error:
            world.send_input(two, 2, push(TOP, 1.0))
        assert error.value.code == grpc.StatusCode.PERMISSION_DENIED
        # Refused whole, with the field named: a player the session does not have.
        with pytest.raises(fulcrum.FulcrumError) as error:
            world.set_ownership(7, bodies=[TOP])
        assert error.value.code == grpc.StatusCode.NOT_FOUND
        assert error.value.field == "player_id"
        with pytest.raises(fulcrum.FulcrumError) as error:
            world.set_ownership(-1, bodies=[TOP])
        assert error.value.field == "player_id"
