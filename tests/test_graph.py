"""Tests for jaxmotion.scene.graph on hand-built layouts (boxes in metres, z-up)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from jaxmotion.scene.graph import (Reference, Relation, SceneGraph, clip_to_convex, convex_hull,
                                   polygon_area, xy_distance, xy_overlap)
from jaxmotion.scene.rooms import room_to_scene, sample_room


def box(i, category, x0, y0, z0, x1, y1, z1):
    return dict(id=i, category=category, bbox_min=[x0, y0, z0], bbox_max=[x1, y1, z1])


def dining():
    """A table at the origin, chairs at 0.3, 1.0 and 2.5 m from it, a lamp on it, a
    pendant light above it, a shelf far away."""
    return [box(0, "table", 0, 0, 0, 1.0, 1.0, 0.75),
            box(1, "chair", 1.3, 0.2, 0, 1.75, 0.65, 0.9),  # 0.3 m right of the table
            box(2, "chair", -1.45, 0.2, 0, -1.0, 0.65, 0.9),  # 1.0 m left
            box(3, "chair", 0.2, 3.5, 0, 0.65, 3.95, 0.9),  # 2.5 m behind
            box(4, "lamp", 0.4, 0.4, 0.75, 0.6, 0.6, 1.2),  # stands on the table
            box(5, "light", 0.3, 0.3, 1.9, 0.7, 0.7, 2.1),  # hangs 1.15 m above the table
            box(6, "bookshelf", 5.0, 5.0, 0, 6.0, 5.4, 2.0)]


def test_xy_distance_and_overlap():
    a, b = (0, 0, 1, 1), (2, 0, 3, 1)
    assert xy_distance(a, b) == 1.0 and xy_distance(b, a) == 1.0
    assert np.isclose(xy_distance(a, (4, 5, 5, 6)), 5.0)  # diagonal: hypot(3, 4)
    assert xy_distance(a, (0.5, 0.5, 2, 2)) == 0.0 and xy_distance(a, (1, 0, 2, 1)) == 0.0
    assert np.isclose(xy_overlap(a, (0.5, 0.5, 2, 2)), 0.25) and xy_overlap(a, b) == 0.0


def test_closest_and_farthest():
    g = SceneGraph(dining())
    assert g.closest("chair", 0) == {1} and g.farthest("chair", 0) == {3}
    assert g.closest("chair", 3) == {1}  # 2.92 m against 3.09 m
    assert g.closest("chair", 1) == {2} and g.farthest("chair", 1) == {3}  # never itself
    assert g.closest("sofa", 0) == frozenset()
    assert g.resolve(Reference("chair", "closest", ("table",))) == {1}
    assert g.resolve(Reference("chair", "farthest", ("table",))) == {3}
    assert g.resolve(Reference("chair", "closest", ("bookshelf",))) == {3}
    assert g.resolve(Reference("chair", "closest", ("bed",))) == frozenset()  # no such anchor


def test_ties_are_not_unique():
    objs = [box(0, "table", 0, 0, 0, 1, 1, 0.75), box(1, "chair", 1.5, 0, 0, 2, 0.5, 0.9),
            box(2, "chair", -1.0, 0, 0, -0.5, 0.5, 0.9)]  # both 0.5 m from the table
    g = SceneGraph(objs)
    assert g.closest("chair", 0) == {1, 2} and g.farthest("chair", 0) == {1, 2}
    assert not [r for r in g.relations if r.predicate in ("closest", "farthest")]
    objs[2] = box(2, "chair", -1.04, 0, 0, -0.54, 0.5, 0.9)  # 4 cm farther: still a tie
    assert SceneGraph(objs).closest("chair", 0) == {1, 2}
    objs[2] = box(2, "chair", -1.1, 0, 0, -0.6, 0.5, 0.9)  # 10 cm farther: resolved
    g = SceneGraph(objs)
    assert g.closest("chair", 0) == {1} and g.farthest("chair", 0) == {2}
    assert Relation("closest", 1, (0,)) in g.relations


def test_above_below():
    g = SceneGraph(dining())
    assert g.is_above(5, 0) and g.is_below(0, 5) and not g.is_above(0, 5)
    assert g.is_above(5, 4)  # 0.7 m above the lamp's top too
    assert not g.is_above(5, 1)  # no xy overlap with the chair
    assert not g.is_above(4, 0)  # resting on it: no gap
    near = [box(0, "table", 0, 0, 0, 1, 1, 0.75), box(1, "shelf", 0, 0, 0.80, 1, 1, 0.9)]
    assert not SceneGraph(near).is_above(1, 0)  # a 5 cm gap is not "above"
    near[1] = box(1, "shelf", 0, 0, 0.82, 1, 1, 0.9)
    assert SceneGraph(near).is_above(1, 0)  # a 7 cm gap is
    assert g.resolve(Reference("light", "above", ("table",))) == {5}
    assert g.resolve(Reference("table", "below", ("light",))) == {0}
    assert g.resolve(Reference("chair", "below", ("light",))) == frozenset()


def test_on_supporting():
    g = SceneGraph(dining())
    assert g.is_on(4, 0) and g.is_supporting(0, 4)
    assert not g.is_on(0, 4) and not g.is_on(5, 0) and not g.is_on(1, 0)
    objs = [box(0, "desk", 0, 0, 0, 1, 1, 0.75), box(1, "lamp", 0.2, 0.2, 0.78, 0.4, 0.4, 1.2),
            box(2, "lamp", 1.2, 0.2, 0.75, 1.4, 0.4, 1.2),  # beside the desk, not on it
            box(3, "lamp", 0.5, 0.5, 0.85, 0.7, 0.7, 1.2)]  # 10 cm above: floating
    g = SceneGraph(objs)
    assert g.is_on(1, 0) and not g.is_on(2, 0) and not g.is_on(3, 0)
    assert g.resolve(Reference("lamp", "on", ("desk",))) == {1}
    assert g.resolve(Reference("desk", "supporting", ("lamp",))) == {0}
    assert Relation("on", 1, (0,)) in g.relations and Relation("supporting", 0, (1,)) in g.relations


def between_layout(tx0, ty0, tx1, ty1):
    return SceneGraph([box(0, "sofa", 0, 0, 0, 2, 1, 0.8), box(1, "bed", 4, 0, 0, 6, 1, 0.6),
                       box(2, "table", tx0, ty0, 0, tx1, ty1, 0.75)])


def test_between():
    assert between_layout(2.5, 0.0, 3.5, 1.0).is_between(2, 0, 1)  # fully in the gap
    assert between_layout(2.5, 0.0, 3.5, 1.0).is_between(2, 1, 0)  # order of anchors
    assert between_layout(2.5, 0.4, 3.5, 1.4).is_between(2, 0, 1)  # 60 % inside the hull
    assert not between_layout(2.5, 0.6, 3.5, 1.6).is_between(2, 0, 1)  # 40 % inside
    assert not between_layout(2.5, 3.0, 3.5, 4.0).is_between(2, 0, 1)  # behind them
    assert between_layout(1.95, 0.0, 2.95, 1.0).is_between(2, 0, 1)  # 5 % on the sofa
    assert not between_layout(1.8, 0.0, 2.8, 1.0).is_between(2, 0, 1)  # 20 % on the sofa
    assert not between_layout(2.5, 0.0, 3.5, 1.0).is_between(0, 2, 1)  # the sofa is not
    g = between_layout(2.5, 0.0, 3.5, 1.0)
    assert g.resolve(Reference("table", "between", ("sofa", "bed"))) == {2}
    assert g.resolve(Reference("table", "between", ("bed", "sofa"))) == {2}
    assert Relation("between", 2, (0, 1)) in g.relations
    # A diagonal pair of anchors: the hull is a slanted hexagon, not their joint box.
    diag = SceneGraph([box(0, "sofa", 0, 0, 0, 1, 1, 1), box(1, "bed", 3, 3, 0, 4, 4, 1),
                       box(2, "table", 1.6, 1.6, 0, 2.4, 2.4, 1),
                       box(3, "stool", 0, 3, 0, 0.8, 3.8, 1)])
    assert diag.is_between(2, 0, 1) and not diag.is_between(3, 0, 1)


def test_sentences_and_references():
    g = SceneGraph(dining())
    s = g.sentences()
    assert "chair 1 is near table 0" in s and "chair 3 is far from table 0" in s
    assert "lamp 4 is on table 0" in s and "table 0 is supporting lamp 4" in s
    assert "light 5 is above table 0" in s and "table 0 is below light 5" in s
    assert g.categories == sorted({o["category"] for o in dining()}) and g.name(4) == "lamp 4"
    with pytest.raises(ValueError):
        Reference("chair", "between", ("sofa",))
    with pytest.raises(ValueError):
        Reference("chair", "next to", ("sofa",))
    with pytest.raises(ValueError):
        Reference("chair", None, ("sofa",))
    assert g.resolve(Reference("chair")) == {1, 2, 3}


def test_any_anchor_instance_counts():
    objs = dining() + [box(7, "table", 1.0, 4.5, 0, 2.0, 5.0, 0.75)]  # 0.65 m from chair 3
    g = SceneGraph(objs)  # two tables: "closest to the table" means either of them
    assert g.resolve(Reference("chair", "closest", ("table",))) == {1, 3}


def test_graph_from_room_and_scene():
    room = sample_room(3)
    g1, g2 = SceneGraph(room), SceneGraph(room_to_scene(room, 500, 0))
    assert g1.ids == list(range(len(room.objects))) and g1.relations == g2.relations
    assert all(isinstance(s, str) for s in g1.sentences())
    assert SceneGraph(list(room.objects)).relations == g1.relations


def test_hull_and_clip():
    hull = convex_hull([(0, 0), (2, 0), (2, 2), (0, 2), (1, 1), (1, 0)])
    assert len(hull) == 4 and np.isclose(polygon_area(hull), 4.0)
    rect = [(1, 1), (3, 1), (3, 3), (1, 3)]
    assert np.isclose(polygon_area(clip_to_convex(rect, hull)), 1.0)
    assert clip_to_convex([(5, 5), (6, 5), (6, 6), (5, 6)], hull) == []


coords = st.floats(-3, 3, allow_nan=False)


@given(st.lists(st.tuples(coords, coords), min_size=3, max_size=10), coords, coords,
       st.floats(0.1, 2), st.floats(0.1, 2))
def test_clip_area_bounds(points, x, y, w, h):
    hull = convex_hull(points)
    rect = [(x, y), (x + w, y), (x + w, y + h), (x, y + h)]
    area = polygon_area(clip_to_convex(rect, hull)) if len(hull) >= 3 else 0.0
    assert -1e-9 <= area <= min(w * h, polygon_area(hull)) + 1e-9
    # Monte Carlo check of the clipped area against the hull's half-planes.
    if len(hull) >= 3:
        rng = np.random.default_rng(0)
        p = rng.uniform((x, y), (x + w, y + h), (4000, 2))
        inside = np.ones(len(p), bool)
        for a, b in zip(hull, hull[1:] + hull[:1]):
            inside &= (b[0] - a[0]) * (p[:, 1] - a[1]) - (b[1] - a[1]) * (p[:, 0] - a[0]) >= 0
        assert abs(inside.mean() * w * h - area) <= 0.05 * w * h + 1e-9


@given(coords, coords, st.floats(0.1, 2), st.floats(0.1, 2), coords, coords, st.floats(0.1, 2),
       st.floats(0.1, 2))
def test_clip_of_rectangles_is_overlap(x, y, w, h, u, v, a, b):
    hull = convex_hull([(u, v), (u + a, v), (u + a, v + b), (u, v + b)])
    rect = [(x, y), (x + w, y), (x + w, y + h), (x, y + h)]
    clipped = polygon_area(clip_to_convex(rect, hull))
    assert np.isclose(clipped, xy_overlap((x, y, x + w, y + h), (u, v, u + a, v + b)), atol=1e-9)
