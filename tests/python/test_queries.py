"""Queries against the pyramid (the CLI test's cases, through the Python API)."""

import pytest

import fulcrum
from conftest import SCENES


@pytest.fixture(scope="module")
def pyramid(client):
    world = client.create_world(SCENES / "pyramid.json")
    world.step(60)
    yield world
    world.delete()


def test_a_ray_down_hits_the_top_box(pyramid):
    hit = pyramid.ray_cast((0, 50), (0, -60))
    # The top box (body 210) of a 20-row pyramid of 1 m boxes: its top face near y = 20.
    assert hit.body == fulcrum.Handle(210, 1)
    assert hit.point[1] == pytest.approx(20.0, abs=0.05)
    assert hit.normal[1] == pytest.approx(1.0, abs=1e-3)
    assert hit.fraction == pytest.approx((50 - hit.point[1]) / 60, rel=1e-9)


def test_a_ray_through_the_bottom_row_hits_all_twenty_boxes(pyramid):
    hits = pyramid.ray_cast_all((-30, 0.5), (60, 0))
    assert len(hits) == 20
    assert [h.fraction for h in hits] == sorted(h.fraction for h in hits)
    assert pyramid.ray_cast((-30, 0.5), (60, 0)) == hits[0]


def test_overlaps_and_filters(pyramid):
    top = pyramid.frame().positions[210]
    shapes = pyramid.overlap_point(top)
    assert [s.body for s in shapes] == [fulcrum.Handle(210, 1)]
    assert pyramid.overlap_aabb((-1, 0), (1, 1), mask_bits=0) == []
    assert len(pyramid.overlap_aabb((-1, 0), (1, 1))) >= 2  # boxes and the ground
    assert pyramid.ray_cast((0, 50), (0, -60), mask_bits=0) is None


def test_a_bad_query_is_refused_with_its_field(pyramid):
    with pytest.raises(fulcrum.FulcrumError) as error:
        pyramid.ray_cast((0, 0), (0, 0))
    assert error.value.code.name == "INVALID_ARGUMENT"
    assert error.value.field.startswith("ray_cast.translation")
