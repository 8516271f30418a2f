"""Sr3D / ReferIt3D spatial relations between object boxes, as a queryable scene graph.

Host-side numpy. Objects are the dicts of a room's or scene's object table (``id``,
``category``, axis-aligned ``bbox_min`` / ``bbox_max`` in metres, z-up). Relations, with
the thresholds of the object-centric pipeline (Cen et al. 2024) as defaults:

- ``closest`` / ``farthest``: among the instances of the target's class (the anchor itself
  excluded), the one with the smallest / largest horizontal distance between the xy
  boxes (0 when they touch). Instances within ``tie_tol`` of the best are tied, and a
  tied relation names all of them (so it does not single out one object).
- ``above`` / ``below``: the xy boxes overlap and the vertical gap between them exceeds
  ``above_gap`` (6 cm).
- ``on`` / ``supporting``: the xy boxes overlap, the target's bottom lies within
  ``on_tol`` of the anchor's top and its top is higher (it rests on the anchor).
- ``between``: at least ``between_inside`` (50 %) of the target's xy box lies inside the
  convex hull of the two anchors' xy boxes, and it overlaps each anchor by at most
  ``between_overlap`` (10 %) of its own area.

Sentences for a grounding prompt read "chair 4 is near table 0" (``closest``), "chair 2 is
far from table 0", "lamp 5 is on nightstand 3", "nightstand 3 is supporting lamp 5",
"picture 6 is above bed 1", "bed 1 is below picture 6", "table 2 is between sofa 1 and
tv 4"; ``closest`` / ``farthest`` are listed for classes with at least two instances.
"""

from __future__ import annotations

import dataclasses
import itertools
from functools import cached_property

import numpy as np

RELATIONS = ("closest", "farthest", "above", "below", "on", "supporting", "between")
_PHRASES = {"closest": "is near", "farthest": "is far from", "above": "is above",
            "below": "is below", "on": "is on", "supporting": "is supporting",
            "between": "is between"}


@dataclasses.dataclass(frozen=True)
class Reference:
    """A parsed referring expression: "the <target> [<relation> <anchors>]".

    ``relation`` None means the plain "the <target>"; ``between`` takes two anchor
    classes, the other relations one.
    """

    target: str
    relation: str | None = None
    anchors: tuple[str, ...] = ()

    def __post_init__(self):
        object.__setattr__(self, "anchors", tuple(self.anchors))
        want = 0 if self.relation is None else 2 if self.relation == "between" else 1
        if self.relation is not None and self.relation not in RELATIONS:
            raise ValueError(f"unknown relation {self.relation!r}; choose from {RELATIONS}")
        if len(self.anchors) != want:
            raise ValueError(f"relation {self.relation!r} takes {want} anchor classes, "
                             f"got {self.anchors!r}")


@dataclasses.dataclass(frozen=True)
class Relation:
    """One edge: ``subject`` <predicate> ``anchors`` (object ids)."""

    predicate: str
    subject: int
    anchors: tuple[int, ...]


def xy_distance(a, b) -> float:
    """Horizontal distance (m) between rectangles (xmin, ymin, xmax, ymax); 0 if they touch."""
    dx = max(0.0, b[0] - a[2], a[0] - b[2])
    dy = max(0.0, b[1] - a[3], a[1] - b[3])
    return float(np.hypot(dx, dy))


def xy_overlap(a, b) -> float:
    """Shared area (m^2) of rectangles (xmin, ymin, xmax, ymax)."""
    return max(0.0, min(a[2], b[2]) - max(a[0], b[0])) * max(0.0, min(a[3], b[3]) - max(a[1], b[1]))


def _cross(o, a, b):
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def convex_hull(points) -> list[tuple[float, float]]:
    """Counter-clockwise convex hull of 2-d points (Andrew's monotone chain)."""
    pts = sorted(set(map(tuple, np.asarray(points, float).tolist())))
    if len(pts) < 3:
        return pts
    lower, upper = [], []
    for chain, seq in ((lower, pts), (upper, pts[::-1])):
        for p in seq:
            while len(chain) >= 2 and _cross(chain[-2], chain[-1], p) <= 0:
                chain.pop()
            chain.append(p)
    return lower[:-1] + upper[:-1]


def polygon_area(poly) -> float:
    """Area (m^2) of a simple polygon given as a vertex list."""
    if len(poly) < 3:
        return 0.0
    p = np.asarray(poly, float)
    x, y = p[:, 0], p[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def clip_to_convex(poly, hull) -> list:
    """Sutherland-Hodgman: the part of polygon ``poly`` inside the CCW convex ``hull``."""
    for p, q in zip(hull, hull[1:] + hull[:1]):
        out = []
        for u, v in zip(poly, poly[1:] + poly[:1]):
            su, sv = _cross(p, q, u), _cross(p, q, v)
            if su >= 0:
                out.append(u)
            if (su >= 0) != (sv >= 0):
                t = su / (su - sv)
                out.append((u[0] + t * (v[0] - u[0]), u[1] + t * (v[1] - u[1])))
        poly = out
        if not poly:
            break
    return poly


def _corners(r):
    return [(r[0], r[1]), (r[2], r[1]), (r[2], r[3]), (r[0], r[3])]


class SceneGraph:
    """Relations between the objects of a room / scene (see the module docstring).

    Args:
      objects: a ``Room``, a ``Scene`` (anything with ``.objects``) or an iterable of
        object dicts with ``id``, ``category``, ``bbox_min``, ``bbox_max``.
      tie_tol, above_gap, on_tol: metres; between_inside, between_overlap: fractions.
    """

    def __init__(self, objects, *, tie_tol=0.05, above_gap=0.06, on_tol=0.04,
                 between_inside=0.5, between_overlap=0.1):
        objects = getattr(objects, "objects", objects)
        self.objects = {int(o["id"]): dict(o) for o in objects}
        self.tie_tol, self.above_gap, self.on_tol = tie_tol, above_gap, on_tol
        self.between_inside, self.between_overlap = between_inside, between_overlap
        self._lo = {i: np.asarray(o["bbox_min"], float) for i, o in self.objects.items()}
        self._hi = {i: np.asarray(o["bbox_max"], float) for i, o in self.objects.items()}
        self._by_class: dict[str, list[int]] = {}
        for i in sorted(self.objects):
            self._by_class.setdefault(self.objects[i]["category"], []).append(i)

    # ------------------------------------------------------------------ lookup
    @property
    def ids(self) -> list[int]:
        return sorted(self.objects)

    @property
    def categories(self) -> list[str]:
        """The room's class list, sorted."""
        return sorted(self._by_class)

    def category(self, i: int) -> str:
        return self.objects[i]["category"]

    def instances(self, category: str) -> list[int]:
        """Ids of the objects of a class (empty when there are none)."""
        return list(self._by_class.get(category, ()))

    def count(self, category: str) -> int:
        return len(self._by_class.get(category, ()))

    def name(self, i: int) -> str:
        """"<category> <id>", the way prompts name an object."""
        return f"{self.category(i)} {i}"

    def foot(self, i: int) -> tuple[float, float, float, float]:
        """xy box (xmin, ymin, xmax, ymax) of object i (m)."""
        return (*self._lo[i][:2].tolist(), *self._hi[i][:2].tolist())

    def distance(self, i: int, j: int) -> float:
        """Horizontal distance between the boxes of objects i and j (m)."""
        return xy_distance(self.foot(i), self.foot(j))

    # ------------------------------------------------------------------ relations
    def _extreme(self, category, anchor, sign):
        cands = [c for c in self.instances(category) if c != anchor]
        if not cands:
            return frozenset()
        d = np.array([sign * self.distance(c, anchor) for c in cands])
        return frozenset(c for c, v in zip(cands, d) if v <= d.min() + self.tie_tol)

    def closest(self, category: str, anchor: int) -> frozenset[int]:
        """Instances of ``category`` closest to object ``anchor`` (ties within tie_tol)."""
        return self._extreme(category, anchor, 1.0)

    def farthest(self, category: str, anchor: int) -> frozenset[int]:
        """Instances of ``category`` farthest from object ``anchor`` (ties within tie_tol)."""
        return self._extreme(category, anchor, -1.0)

    def is_above(self, t: int, a: int) -> bool:
        """Object t is above a: xy overlap and a vertical gap > above_gap."""
        return (t != a and xy_overlap(self.foot(t), self.foot(a)) > 1e-9
                and self._lo[t][2] - self._hi[a][2] > self.above_gap)

    def is_below(self, t: int, a: int) -> bool:
        return self.is_above(a, t)

    def is_on(self, t: int, a: int) -> bool:
        """Object t rests on a: xy overlap, t's bottom within on_tol of a's top, t higher."""
        return (t != a and xy_overlap(self.foot(t), self.foot(a)) > 1e-9
                and abs(self._lo[t][2] - self._hi[a][2]) <= self.on_tol
                and self._hi[t][2] > self._hi[a][2])

    def is_supporting(self, t: int, a: int) -> bool:
        return self.is_on(a, t)

    def is_between(self, t: int, a: int, b: int) -> bool:
        """Object t lies between a and b (see the module docstring)."""
        if len({t, a, b}) < 3:
            return False
        ft, fa, fb = self.foot(t), self.foot(a), self.foot(b)
        area = (ft[2] - ft[0]) * (ft[3] - ft[1])
        if area <= 1e-12:
            return False
        if max(xy_overlap(ft, fa), xy_overlap(ft, fb)) > self.between_overlap * area:
            return False
        lo, hi = np.minimum(fa[:2], fb[:2]), np.maximum(fa[2:], fb[2:])
        if ft[0] >= hi[0] or ft[2] <= lo[0] or ft[1] >= hi[1] or ft[3] <= lo[1]:
            return False  # cheap rejection: outside the anchors' joint box
        hull = convex_hull(_corners(fa) + _corners(fb))
        inside = polygon_area(clip_to_convex(_corners(ft), hull))
        return inside >= self.between_inside * area

    @cached_property
    def relations(self) -> tuple[Relation, ...]:
        """Every relation that holds (closest / farthest only when not tied)."""
        out = []
        for a in self.ids:
            for cat in self.categories:
                if cat == self.category(a) or self.count(cat) < 2:
                    continue
                for pred, hit in (("closest", self.closest(cat, a)),
                                  ("farthest", self.farthest(cat, a))):
                    if len(hit) == 1:
                        out.append(Relation(pred, next(iter(hit)), (a,)))
        for t, a in itertools.permutations(self.ids, 2):
            for pred in ("above", "below", "on", "supporting"):
                if getattr(self, f"is_{pred}")(t, a):
                    out.append(Relation(pred, t, (a,)))
        for t in self.ids:
            others = [i for i in self.ids if i != t]
            for a, b in itertools.combinations(others, 2):
                if self.is_between(t, a, b):
                    out.append(Relation("between", t, (a, b)))
        return tuple(out)

    def sentences(self) -> list[str]:
        """The relations as short sentences, e.g. "chair 4 is near table 0"."""
        out = []
        for r in self.relations:
            anchors = " and ".join(self.name(a) for a in r.anchors)
            out.append(f"{self.name(r.subject)} {_PHRASES[r.predicate]} {anchors}")
        return out

    def resolve(self, reference: Reference) -> frozenset[int]:
        """Ids of the target-class objects that fit a reference.

        An anchor class with several instances counts as "any of them". Exactly one id
        back means the reference singles out one object, as Sr3D requires.
        """
        cands = self.instances(reference.target)
        if reference.relation is None:
            return frozenset(cands)
        groups = [self.instances(c) for c in reference.anchors]
        rel = reference.relation
        if rel in ("closest", "farthest"):
            hit = set()
            for a in groups[0]:
                hit |= getattr(self, rel)(reference.target, a)
            return frozenset(hit)
        if rel == "between":
            return frozenset(t for t in cands if any(
                self.is_between(t, a, b) for a in groups[0] for b in groups[1]))
        test = getattr(self, f"is_{rel}")
        return frozenset(t for t in cands if any(test(t, a) for a in groups[0]))


def as_scene_graph(x) -> SceneGraph:
    """``x`` if it already is a :class:`SceneGraph`, else ``SceneGraph(x)``."""
    return x if isinstance(x, SceneGraph) else SceneGraph(x)
