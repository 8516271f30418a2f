"""Collision-free furniture placement on a floor plan (host-side numpy, metres, z-up).

A :class:`Layout` holds the floor (a union of disjoint axis-aligned rectangles), its walls
and the pieces placed so far. Every floor-standing piece keeps its xy box at least
:data:`MARGIN` from every other one, and a piece with a front keeps a *clear zone* in
front of it (:data:`CLEAR_DEPTH` deep; :data:`DOOR_CLEAR` for doors) that no other
footprint may enter, so a person can approach it. Pieces standing on another's top
(lamp, tv) or hung above it (picture) only need to avoid every other box in 3D.
Placement helpers return the placed :class:`Item` or None when the proposal collides.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from jaxmotion.scene._parts import rot90
from jaxmotion.scene.furniture import SEAT_CATEGORIES, SMALL_OBJECTS, WALL_MOUNTED, Model

MARGIN = 0.05  # min xy gap between floor-standing boxes (m)
CLEAR_DEPTH = 0.6  # free floor in front of a piece with a front (m)
DOOR_CLEAR = 0.9  # free floor in front of a door (m)
ZONE_WIDTH = (0.6, 1.0)  # clear-zone width: the front face's length, clipped (seats: >= 0.6)
WALL_GAP = (0.005, 0.02)  # gap between a wall and the back of a piece against it (m)


def overlap(a, b) -> float:
    """Area (m^2) shared by xy rectangles a, b = (xmin, ymin, xmax, ymax)."""
    return max(0.0, min(a[2], b[2]) - max(a[0], b[0])) * max(0.0, min(a[3], b[3]) - max(a[1], b[1]))


def gap(a, b) -> float:
    """Euclidean xy distance (m) between rectangles a, b (0 when they touch or overlap)."""
    dx = max(0.0, b[0] - a[2], a[0] - b[2])
    dy = max(0.0, b[1] - a[3], a[1] - b[3])
    return float(np.hypot(dx, dy))


def area(a) -> float:
    return max(0.0, a[2] - a[0]) * max(0.0, a[3] - a[1])


def turn(v, k):
    """xy vector v turned by k quarter turns (exact for axis vectors)."""
    return np.rint(rot90(k)[:2, :2] @ np.asarray(v, float))


def quarter_turns(local, world) -> int:
    """The k in 0..3 with turn(local, k) == world (both axis-aligned unit xy vectors)."""
    return next(k for k in range(4) if np.allclose(turn(local, k), world))


def world_box(model: Model, k: int, t) -> tuple[np.ndarray, np.ndarray]:
    """(lo [3], hi [3]) of model turned k quarter turns and shifted by t [3]."""
    c = np.stack([model.lo, model.hi]) @ rot90(k).T + np.asarray(t, float)
    return c.min(0), c.max(0)


def clear_zone(foot, front, depth, seat):
    """Rectangle in front of footprint ``foot`` along axis unit ``front`` (xy)."""
    axis = 0 if abs(front[0]) > 0.5 else 1
    other, sign = 1 - axis, front[axis] > 0
    face = foot[axis + 2] if sign else foot[axis]
    length = foot[other + 2] - foot[other]
    width = min(ZONE_WIDTH[1], max(length, ZONE_WIDTH[0]) if seat else length)
    mid = 0.5 * (foot[other] + foot[other + 2])
    lo, hi = [0.0, 0.0], [0.0, 0.0]
    lo[axis], hi[axis] = (face, face + depth) if sign else (face - depth, face)
    lo[other], hi[other] = mid - width / 2, mid + width / 2
    return (lo[0], lo[1], hi[0], hi[1])


@dataclasses.dataclass
class Item:
    """A placed piece: ``model`` turned ``k`` quarter turns about z, then shifted by ``t``."""

    index: int
    model: Model
    k: int
    t: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    front: np.ndarray | None = None
    zone: tuple | None = None
    parent: int | None = None
    wall: int | None = None  # index of the wall it backs onto
    s: float = 0.0  # its centre's distance along that wall (m)

    @property
    def category(self) -> str:
        return self.model.category

    @property
    def foot(self) -> tuple[float, float, float, float]:
        return (self.lo[0], self.lo[1], self.hi[0], self.hi[1])


class Layout:
    """Floor plan plus placed items; ``rng`` drives every proposal."""

    def __init__(self, rng, rects, walls, height):
        self.rng, self.rects, self.walls, self.height = rng, rects, walls, height
        self.items: list[Item] = []

    def inside(self, r) -> bool:
        """Rectangle r lies on the floor (the floor rectangles are disjoint)."""
        return sum(overlap(r, f) for f in self.rects) >= area(r) - 1e-9

    def fits(self, foot, zone) -> bool:
        if not self.inside(foot) or (zone is not None and not self.inside(zone)):
            return False
        for it in self.items:
            if it.parent is not None:
                continue
            if gap(foot, it.foot) < MARGIN - 1e-9 or (it.zone and overlap(foot, it.zone) > 1e-9):
                return False
            if zone is not None and overlap(zone, it.foot) > 1e-9:
                return False
        return True

    def furniture_count(self) -> int:
        """Floor-standing furniture so far (doors, windows, pictures, lamps, tvs excluded)."""
        skip = WALL_MOUNTED + SMALL_OBJECTS
        return sum(it.category not in skip for it in self.items)

    def add(self, model, k, t, *, parent=None, wall=None, s=0.0) -> Item | None:
        """Place model if it fits (see the module docstring); returns the item or None."""
        lo, hi = world_box(model, k, t)
        foot, front, zone = (lo[0], lo[1], hi[0], hi[1]), None, None
        if parent is not None:
            if any(np.all(np.minimum(hi, it.hi) - np.maximum(lo, it.lo) > 1e-9)
                   for it in self.items if it.index != parent):
                return None
            front = turn(model.fronts[0], k) if model.fronts else None
        else:
            fronts = [turn(f, k) for f in model.fronts]
            self.rng.shuffle(fronts)
            depth = DOOR_CLEAR if model.category == "door" else CLEAR_DEPTH
            seat = model.category in SEAT_CATEGORIES
            for f in fronts:
                zone = clear_zone(foot, f, depth, seat)
                if self.fits(foot, zone):
                    front = f
                    break
            if (fronts and front is None) or (not fronts and not self.fits(foot, None)):
                return None
        item = Item(len(self.items), model, k, np.asarray(t, float), lo, hi, front, zone,
                    parent, wall, s)
        self.items.append(item)
        return item

    # ------------------------------------------------------------------ proposals
    def on_wall(self, model, *, back=(0.0, -1.0), wall=None, s=None, gap=None, z=0.0,
                parent=None, tries=20) -> Item | None:
        """Back (local direction ``back``) against a wall: a random one weighted by length,
        at a random position ``s`` along it, unless given."""
        lengths = np.array([np.hypot(w[2] - w[0], w[3] - w[1]) for w in self.walls])
        for _ in range(1 if s is not None else tries):
            wi = wall if wall is not None else int(
                self.rng.choice(len(lengths), p=lengths / lengths.sum()))
            x0, y0, x1, y1 = self.walls[wi]
            u = np.array([x1 - x0, y1 - y0]) / lengths[wi]
            n = np.array([-u[1], u[0]])  # interior is on the left of a counter-clockwise wall
            k = quarter_turns(back, -n)
            lo, hi = world_box(model, k, (0.0, 0.0, 0.0))
            ext = hi - lo
            along, depth = abs(u @ ext[:2]) / 2, abs(n @ ext[:2])
            if lengths[wi] < 2 * along:
                continue
            ss = self.rng.uniform(along, lengths[wi] - along) if s is None else s
            if not along - 1e-9 <= ss <= lengths[wi] - along + 1e-9:
                return None
            g = self.rng.uniform(*WALL_GAP) if gap is None else gap
            c = np.array([x0, y0]) + u * ss + n * (g + depth / 2)
            item = self.add(model, k, (c[0], c[1], z), parent=parent, wall=wi, s=ss)
            if item is not None:
                return item
        return None

    def free(self, model, tries=30) -> Item | None:
        """Anywhere on the floor; a piece with a front mostly faces the room's middle."""
        lo = np.min([r[:2] for r in self.rects], axis=0)
        hi = np.max([r[2:] for r in self.rects], axis=0)
        for _ in range(tries):
            c = self.rng.uniform(lo, hi)
            k = int(self.rng.integers(4))
            if model.fronts and self.rng.random() < 0.7:
                d = 0.5 * (lo + hi) - c
                axis = int(np.argmax(np.abs(d)))
                k = quarter_turns(model.fronts[0], np.eye(2)[axis] * np.sign(d[axis] or 1.0))
            item = self.add(model, k, (c[0], c[1], 0.0))
            if item is not None:
                return item
        return None

    def facing(self, model, anchor: Item, *, sides=None, tries=12) -> Item | None:
        """In front of one side of ``anchor``, facing it across a clear zone (chairs at a
        table or desk, armchairs at a coffee table)."""
        a = anchor.foot
        sides = sides if sides is not None else [(1, 0), (-1, 0), (0, 1), (0, -1)]
        for _ in range(tries):
            s = np.asarray(sides[self.rng.integers(len(sides))], float)
            axis = 0 if abs(s[0]) > 0.5 else 1
            k = quarter_turns(model.fronts[0], -s)
            lo, hi = world_box(model, k, (0.0, 0.0, 0.0))
            half_d = (hi - lo)[axis] / 2
            side_len = a[3 - axis] - a[1 - axis]
            lim = max(0.0, side_len / 2 - 0.15)
            mid = np.array([0.5 * (a[0] + a[2]), 0.5 * (a[1] + a[3])])
            face = a[axis + 2] if s[axis] > 0 else a[axis]
            c = mid.copy()
            c[axis] = face + s[axis] * (CLEAR_DEPTH + MARGIN + self.rng.uniform(0, 0.1) + half_d)
            c[1 - axis] += self.rng.uniform(-lim, lim)
            item = self.add(model, k, (c[0], c[1], 0.0))
            if item is not None:
                return item
        return None

    def in_front(self, model, anchor: Item) -> Item | None:
        """Beyond ``anchor``'s clear zone, aligned with it (a coffee table before a sofa)."""
        f = anchor.front
        axis = 0 if abs(f[0]) > 0.5 else 1
        lo, hi = world_box(model, anchor.k, (0.0, 0.0, 0.0))
        c = 0.5 * (anchor.lo[:2] + anchor.hi[:2])
        face = anchor.hi[axis] if f[axis] > 0 else anchor.lo[axis]
        extra = CLEAR_DEPTH + MARGIN + self.rng.uniform(0.0, 0.25) + (hi - lo)[axis] / 2
        c[axis] = face + f[axis] * extra
        return self.add(model, anchor.k, (c[0], c[1], 0.0))

    def beside(self, model, anchor: Item, sign: int) -> Item | None:
        """Against the same wall as ``anchor``, just to its left (-1) or right (+1)."""
        x0, y0, x1, y1 = self.walls[anchor.wall]
        u = np.abs(np.array([x1 - x0, y1 - y0])) / np.hypot(x1 - x0, y1 - y0)
        mine = (model.hi - model.lo)[0] / 2  # its local x runs along the wall
        half = abs(u @ (anchor.hi - anchor.lo)[:2]) / 2
        s = anchor.s + sign * (half + MARGIN + self.rng.uniform(0.0, 0.08) + mine)
        return self.on_wall(model, wall=anchor.wall, s=s)

    def on_top(self, model, anchor: Item) -> Item | None:
        """Standing on ``anchor``'s top (inset 2 cm), turned like it."""
        lo, hi = world_box(model, anchor.k, (0.0, 0.0, 0.0))
        room = (anchor.hi - anchor.lo)[:2] - (hi - lo)[:2] - 0.04
        if np.any(room < 0):
            return None
        c = anchor.lo[:2] + 0.02 + (hi - lo)[:2] / 2 + self.rng.uniform(0.0, 1.0, 2) * room
        return self.add(model, anchor.k, (c[0], c[1], anchor.hi[2]), parent=anchor.index)

    def above(self, model, anchor: Item) -> Item | None:
        """Hung flush on the wall behind ``anchor``, 15-35 cm above its top."""
        z = anchor.hi[2] + self.rng.uniform(0.15, 0.35)
        x0, y0, x1, y1 = self.walls[anchor.wall]
        u = np.abs(np.array([x1 - x0, y1 - y0])) / np.hypot(x1 - x0, y1 - y0)
        slack = abs(u @ (anchor.hi - anchor.lo)[:2]) / 2 - (model.hi - model.lo)[0] / 2
        if slack < 0 or z + model.hi[2] > self.height - 0.15:
            return None
        s = anchor.s + self.rng.uniform(-0.5, 0.5) * slack
        return self.on_wall(model, wall=anchor.wall, s=s, gap=0.0, z=z, parent=anchor.index)
