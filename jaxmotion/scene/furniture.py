"""Furniture categories and their parametric builders (host-side numpy, metres, z-up).

Every builder takes a ``numpy.random.Generator`` and returns a :class:`Model`: boxes and
upright cylinders (:class:`~jaxmotion.scene._parts.Part`) in object-local coordinates
with the xy box centred on the origin, the floor at z = 0 (windows and pictures start
higher) and the front facing local +y. Sizes follow real furniture; the ranges are in
each builder's docstring. Colours come from per-category palettes with per-instance
jitter.

Semantic ids: NYU40 ids (the ScanNet benchmark classes) where NYU40 has the class;
armchair, coffee table and stool, which NYU40 folds into chair / table / otherfurniture,
get 41, 42, 43 (:data:`NYU40_ID` folds them back).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from jaxmotion.scene._parts import (
    BRIGHT,
    CERAMIC,
    FABRIC,
    LAMINATE,
    METAL,
    WOOD,
    Part,
    bounds,
    leg_set,
    moved,
    part,
    shade,
    tone,
)

CATEGORY_IDS = {
    "wall": 1, "floor": 2, "cabinet": 3, "bed": 4, "chair": 5, "sofa": 6, "table": 7,
    "door": 8, "window": 9, "bookshelf": 10, "picture": 11, "desk": 14, "fridge": 24, "tv": 25,
    "nightstand": 32, "toilet": 33, "sink": 34, "lamp": 35,
    "armchair": 41, "coffee table": 42, "stool": 43,
}
NYU40_ID = {**CATEGORY_IDS, "armchair": 5, "coffee table": 7, "stool": 39}
SEAT_CATEGORIES = ("chair", "armchair", "sofa", "stool", "toilet", "bed")  # sit / stand up
LIE_CATEGORIES = ("bed", "sofa")
WALL_MOUNTED = ("door", "window", "picture")  # built into / hung on a wall
SMALL_OBJECTS = ("lamp", "tv")  # stand on another object's top


@dataclasses.dataclass(frozen=True)
class Model:
    """One piece in object-local coordinates (m): front = +y, xy box centred on 0.

    Attributes:
      category: key of :data:`CATEGORY_IDS`.
      parts: its parts (unlabelled; labels are set when it is placed in a room).
      surface_height: local z of the top of the surface one sits or lies on, else None.
      fronts: local unit xy directions it can be approached from (seat / door facing);
        a bed lists both long sides, the room picks the free one. Empty: any side.
    """

    category: str
    parts: tuple[Part, ...]
    surface_height: float | None = None
    fronts: tuple[tuple[float, float], ...] = ()

    @property
    def lo(self) -> np.ndarray:
        """Box minimum corner [3] (m)."""
        return bounds(self.parts)[0]

    @property
    def hi(self) -> np.ndarray:
        """Box maximum corner [3] (m)."""
        return bounds(self.parts)[1]


def _model(category, parts, surface=None, fronts=((0.0, 1.0),)):
    lo, hi = bounds(parts)
    shift = (-0.5 * (lo[0] + hi[0]), -0.5 * (lo[1] + hi[1]), 0.0)
    return Model(category, tuple(moved(p, 0, shift) for p in parts),
                 None if surface is None else float(surface), tuple(fronts))


def chair(rng):
    """Seat 0.40-0.50 m square, seat top 0.42-0.50 m, 4 legs, backrest 0.35-0.50 m above."""
    w, d, top = rng.uniform(0.40, 0.50), rng.uniform(0.40, 0.50), rng.uniform(0.42, 0.50)
    st, lt, bt = rng.uniform(0.03, 0.06), rng.uniform(0.025, 0.045), rng.uniform(0.03, 0.05)
    frame = tone(rng, WOOD + METAL[1:])
    seat = frame if rng.random() < 0.5 else tone(rng, FABRIC)
    parts = leg_set(w, d, top - st, lt, frame, 0.01, rng.random() < 0.3)
    parts.append(part(-w / 2, w / 2, -d / 2, d / 2, top - st, top, seat))
    bh, style, y0 = rng.uniform(0.35, 0.50), rng.integers(3), -d / 2
    if style == 0:  # solid back panel
        parts.append(part(-w / 2, w / 2, y0, y0 + bt, top, top + bh, seat))
    else:  # two posts with one top rail, or a ladder of two rails
        for x in (-w / 2, w / 2 - lt):
            parts.append(part(x, x + lt, y0, y0 + bt, top, top + bh, frame))
        rail = rng.uniform(0.06, 0.12)
        for z in [top + bh - rail] + ([top + 0.5 * bh - rail] if style == 2 else []):
            parts.append(part(-w / 2 + lt, w / 2 - lt, y0, y0 + bt, z, z + rail, frame))
    return _model("chair", parts, top)


def armchair(rng):
    """Upholstered, 0.66-0.97 m wide, 0.70-0.90 m deep, seat top 0.40-0.46 m, two arms."""
    sw, arm, d = rng.uniform(0.50, 0.65), rng.uniform(0.08, 0.16), rng.uniform(0.70, 0.90)
    w, top, cush = sw + 2 * arm, rng.uniform(0.40, 0.46), rng.uniform(0.08, 0.14)
    back_t, back_top = rng.uniform(0.12, 0.20), rng.uniform(0.75, 1.0)
    arm_top, fabric = top + rng.uniform(0.15, 0.25), tone(rng, FABRIC)
    legs = rng.uniform(0.06, 0.15) if rng.random() < 0.5 else 0.0
    parts = leg_set(w, d, legs, 0.04, tone(rng, WOOD), 0.03) if legs else []
    base = top - cush
    parts += [part(-w / 2, w / 2, -d / 2, d / 2, legs, base, fabric),
              part(-sw / 2, sw / 2, -d / 2 + back_t, d / 2, base, top, shade(fabric, 1.1)),
              part(-w / 2, -sw / 2, -d / 2, d / 2, base, arm_top, fabric),
              part(sw / 2, w / 2, -d / 2, d / 2, base, arm_top, fabric),
              part(-sw / 2, sw / 2, -d / 2, -d / 2 + back_t, base, back_top, fabric)]
    return _model("armchair", parts, top)


def sofa(rng):
    """2-3 seats of 0.55-0.70 m, depth 0.80-1.00 m, seat top 0.40-0.45 m, back 0.75-0.95 m."""
    n, sw, arm = int(rng.integers(2, 4)), rng.uniform(0.55, 0.70), rng.uniform(0.10, 0.22)
    d, top, back_t = rng.uniform(0.80, 1.00), rng.uniform(0.40, 0.45), rng.uniform(0.15, 0.25)
    cush, back_top, fabric = rng.uniform(0.10, 0.16), rng.uniform(0.75, 0.95), tone(rng, FABRIC)
    w, base, half = n * sw + 2 * arm, top - cush, n * sw / 2
    legs = rng.uniform(0.05, 0.12) if rng.random() < 0.5 else 0.0
    parts = leg_set(w, d, legs, 0.05, tone(rng, WOOD + METAL[1:]), 0.04) if legs else []
    arm_top = top + rng.uniform(0.12, 0.25)
    parts += [part(-w / 2, w / 2, -d / 2, d / 2, legs, base, fabric),
              part(-w / 2, -half, -d / 2, d / 2, base, arm_top, fabric),
              part(half, w / 2, -d / 2, d / 2, base, arm_top, fabric),
              part(-half, half, -d / 2, -d / 2 + back_t, base, back_top, fabric)]
    for i in range(n):  # one cushion per seat
        x = -half + i * sw
        parts.append(part(x, x + sw, -d / 2 + back_t, d / 2, base, top, shade(fabric, 1.08)))
    return _model("sofa", parts, top)


def bed(rng):
    """Single (0.90-1.05 m) or double (1.40-1.80 m) x 1.95-2.15 m, mattress top 0.45-0.60 m,
    headboard 0.85-1.20 m high at local -y; sit on either long side (+-x)."""
    double = rng.random() < 0.5
    w = rng.uniform(1.40, 1.80) if double else rng.uniform(0.90, 1.05)
    length, top, mattress = rng.uniform(1.95, 2.15), rng.uniform(0.45, 0.6), rng.uniform(0.18, 0.28)
    ht, hh = rng.uniform(0.04, 0.08), rng.uniform(0.85, 1.20)
    wood, linen = tone(rng, WOOD + LAMINATE[2:]), tone(rng, CERAMIC + FABRIC[3:4], 0.03)
    legs = rng.uniform(0.08, 0.15) if rng.random() < 0.4 else 0.0
    y0, y1 = -length / 2 + ht, length / 2
    parts = [moved(p, 0, (0, ht / 2, 0)) for p in
             (leg_set(w, length - ht, legs, 0.06, wood, 0.02) if legs else [])]
    parts += [part(-w / 2, w / 2, y0, y1, legs, top - mattress, wood),
              part(-w / 2 + 0.02, w / 2 - 0.02, y0 + 0.01, y1 - 0.02, top - mattress, top, linen),
              part(-w / 2, w / 2, -length / 2, y0, 0.0, hh, shade(wood, 0.9))]
    n = 2 if double else 1
    pw, pd = min(rng.uniform(0.50, 0.65), w / n - 0.08), rng.uniform(0.35, 0.45)
    for i in range(n):
        cx = (i - (n - 1) / 2) * w / n
        parts.append(part(cx - pw / 2, cx + pw / 2, y0 + 0.04, y0 + 0.04 + pd, top,
                          top + rng.uniform(0.10, 0.15), tone(rng, CERAMIC, 0.02)))
    if rng.random() < 0.6:  # a blanket over the foot end
        parts.append(part(-w / 2 + 0.01, w / 2 - 0.01, y0 + pd + 0.1, y1 - 0.03, top, top + 0.03,
                          tone(rng, FABRIC + BRIGHT)))
    return _model("bed", parts, top, ((1.0, 0.0), (-1.0, 0.0)))


def table(rng):
    """Rectangular (1.2-2.0 x 0.75-1.0 m), square or round (0.8-1.2 m), 0.72-0.78 m high."""
    style, h, t = rng.integers(3), rng.uniform(0.72, 0.78), rng.uniform(0.03, 0.05)
    if style == 0:
        w, d = rng.uniform(1.2, 2.0), rng.uniform(0.75, 1.0)
    else:
        w = d = rng.uniform(0.8, 1.2)
    wood, top_shape = tone(rng, WOOD + LAMINATE), "cylinder" if style == 2 else "box"
    parts = [part(-w / 2, w / 2, -d / 2, d / 2, h - t, h, wood, top_shape)]
    if style == 2 and rng.random() < 0.5:  # pedestal
        parts += [part(-0.05, 0.05, -0.05, 0.05, 0.03, h - t, wood, "cylinder"),
                  part(-0.25, 0.25, -0.25, 0.25, 0.0, 0.03, shade(wood, 0.8), "cylinder")]
    else:
        inset = 0.15 * w if style == 2 else rng.uniform(0.03, 0.08)
        parts += leg_set(w, d, h - t, rng.uniform(0.04, 0.07), shade(wood, 0.9), inset,
                         rng.random() < 0.4)
    return _model("table", parts, fronts=())


def desk(rng):
    """1.0-1.6 x 0.55-0.75 m, 0.72-0.76 m high, legs or side panels, optional drawers."""
    w, d, h, t = rng.uniform(1.0, 1.6), rng.uniform(0.55, 0.75), rng.uniform(0.72, 0.76), 0.03
    col = tone(rng, WOOD + LAMINATE)
    parts = [part(-w / 2, w / 2, -d / 2, d / 2, h - t, h, col)]
    if rng.random() < 0.5:
        parts += leg_set(w, d, h - t, 0.05, tone(rng, METAL), 0.02)
    else:
        for x in (-w / 2, w / 2 - 0.03):
            parts.append(part(x, x + 0.03, -d / 2 + 0.02, d / 2 - 0.02, 0, h - t, col))
    if rng.random() < 0.5:  # drawer unit on the right, with handles
        x0 = w / 2 - 0.43
        parts.append(part(x0, w / 2 - 0.03, -d / 2 + 0.03, d / 2 - 0.03, 0.02, h - t,
                          shade(col, 0.95)))
        for z in np.linspace(0.15, h - 0.15, 3):
            parts.append(part(x0 + 0.15, x0 + 0.25, d / 2 - 0.03, d / 2 - 0.01, z, z + 0.02,
                              METAL[0]))
    return _model("desk", parts)


def coffee_table(rng):
    """0.8-1.3 x 0.45-0.70 m, 0.38-0.48 m high, optional lower shelf."""
    w, d, h, t = rng.uniform(0.8, 1.3), rng.uniform(0.45, 0.70), rng.uniform(0.38, 0.48), 0.035
    col = tone(rng, WOOD + LAMINATE)
    parts = [part(-w / 2, w / 2, -d / 2, d / 2, h - t, h, col)]
    parts += leg_set(w, d, h - t, 0.045, shade(col, 0.85), 0.03)
    if rng.random() < 0.5:
        parts.append(part(-w / 2 + 0.075, w / 2 - 0.075, -d / 2 + 0.075, d / 2 - 0.075, 0.10,
                          0.12, col))
    return _model("coffee table", parts, fronts=())


def cabinet(rng):
    """Low sideboard (0.8-1.6 m wide, 0.70-1.00 m high) or wardrobe (0.6-1.2 m, 1.6-2.1 m),
    0.40-0.60 m deep, with doors and handles."""
    tall = rng.random() < 0.4
    w = rng.uniform(0.6, 1.2) if tall else rng.uniform(0.8, 1.6)
    h, d = rng.uniform(1.6, 2.1) if tall else rng.uniform(0.70, 1.00), rng.uniform(0.40, 0.60)
    col, plinth = tone(rng, WOOD + LAMINATE), 0.08 if rng.random() < 0.5 else 0.0
    parts = [part(-w / 2, w / 2, -d / 2, d / 2, plinth, h, col)]
    if plinth:
        parts.append(part(-w / 2 + 0.03, w / 2 - 0.03, -d / 2, d / 2 - 0.04, 0, plinth,
                          shade(col, 0.6)))
    n = 1 if w < 0.7 else 2 if w < 1.3 else 3
    dw, zc = (w - 0.02) / n, plinth + 0.5 * (h - plinth) if tall else h - 0.12
    for i in range(n):
        x0 = -w / 2 + 0.01 + i * dw
        parts.append(part(x0 + 0.003, x0 + dw - 0.003, d / 2, d / 2 + 0.015, plinth + 0.02,
                          h - 0.02, shade(col, 1.05)))
        hx = x0 + dw - 0.06 if i % 2 == 0 else x0 + 0.04
        parts.append(part(hx, hx + 0.02, d / 2 + 0.015, d / 2 + 0.035, zc - 0.06, zc + 0.06,
                          METAL[0]))
    return _model("cabinet", parts)


def bookshelf(rng):
    """0.6-1.2 m wide, 0.25-0.40 m deep, 1.0-2.0 m high, shelves every ~0.35 m with books."""
    w, d, h, t = rng.uniform(0.6, 1.2), rng.uniform(0.25, 0.40), rng.uniform(1.0, 2.0), 0.02
    col = tone(rng, WOOD + LAMINATE)
    parts = [part(-w / 2, -w / 2 + t, -d / 2, d / 2, 0, h, col),
             part(w / 2 - t, w / 2, -d / 2, d / 2, 0, h, col),
             part(-w / 2 + t, w / 2 - t, -d / 2, -d / 2 + 0.01, 0, h, shade(col, 0.8))]
    levels = np.linspace(0.0, h - t, max(2, int(round(h / 0.35))) + 1)
    for z in levels:
        parts.append(part(-w / 2 + t, w / 2 - t, -d / 2 + 0.01, d / 2, z, z + t, col))
    for z0, z1 in zip(levels[:-1] + t, levels[1:]):
        x = -w / 2 + t + rng.uniform(0.0, 0.1)
        while x < w / 2 - t - 0.12 and rng.random() < 0.8:  # runs of books, random colours
            bw = min(rng.uniform(0.08, 0.30), w / 2 - t - x)
            bh = min(rng.uniform(0.15, 0.28), z1 - z0 - 0.02)
            parts.append(part(x, x + bw, -d / 2 + 0.02, -d / 2 + 0.02 + 0.7 * (d - 0.02), z0,
                              z0 + bh, tone(rng, BRIGHT + FABRIC)))
            x += bw + rng.uniform(0.0, 0.15)
    return _model("bookshelf", parts)


def toilet(rng):
    """Tank at the back, bowl 0.50-0.60 m long, seat top 0.40-0.44 m, white ceramic."""
    wt, dt = rng.uniform(0.36, 0.46), rng.uniform(0.16, 0.22)
    wb, lb, top = rng.uniform(0.34, 0.40), rng.uniform(0.50, 0.60), rng.uniform(0.40, 0.44)
    white, seat = tone(rng, CERAMIC, 0.02), tone(rng, CERAMIC + LAMINATE[1:2], 0.02)
    y0 = -(dt + lb) / 2
    yb = y0 + dt
    parts = [part(-wt / 2, wt / 2, y0, yb, top - 0.03, rng.uniform(0.72, 0.82), white),
             part(-0.35 * wb, 0.35 * wb, y0 + 0.02, yb + 0.7 * lb, 0.0, 0.22, white),
             part(-wb / 2, wb / 2, yb, yb + lb, 0.22, top - 0.03, white),
             part(-wb / 2, wb / 2, yb + 0.02, yb + lb, top - 0.03, top, seat)]
    return _model("toilet", parts, top)


def stool(rng):
    """Round or square top 0.30-0.40 m, seat height 0.42-0.65 m, legs or a post; no front."""
    s, top, t = rng.uniform(0.30, 0.40), rng.uniform(0.42, 0.65), rng.uniform(0.03, 0.05)
    rnd, col = rng.random() < 0.5, tone(rng, WOOD + METAL + BRIGHT[:2])
    parts = [part(-s / 2, s / 2, -s / 2, s / 2, top - t, top, col, "cylinder" if rnd else "box")]
    if rng.random() < 0.3:
        parts += [part(-0.025, 0.025, -0.025, 0.025, 0.02, top - t, METAL[0], "cylinder"),
                  part(-s / 2, s / 2, -s / 2, s / 2, 0.0, 0.02, METAL[1], "cylinder")]
    else:
        parts += leg_set(s, s, top - t, 0.03, shade(col, 0.85), 0.15 * s if rnd else 0.01, rnd)
    return _model("stool", parts, top, fronts=())


def nightstand(rng):
    """0.40-0.55 x 0.35-0.45 m, 0.45-0.65 m high, 1-3 drawers."""
    w, d, h = rng.uniform(0.40, 0.55), rng.uniform(0.35, 0.45), rng.uniform(0.45, 0.65)
    col = tone(rng, WOOD + LAMINATE)
    legs = rng.uniform(0.08, 0.15) if rng.random() < 0.4 else 0.0
    parts = leg_set(w, d, legs, 0.03, col, 0.02) if legs else []
    parts.append(part(-w / 2, w / 2, -d / 2, d / 2, legs, h, col))
    edges = np.linspace(legs + 0.02, h - 0.02, int(rng.integers(1, 4)) + 1)
    for z0, z1 in zip(edges[:-1], edges[1:]):
        zc = 0.5 * (z0 + z1)
        parts += [part(-w / 2 + 0.02, w / 2 - 0.02, d / 2, d / 2 + 0.012, z0 + 0.004, z1 - 0.004,
                       shade(col, 1.08)),
                  part(-0.05, 0.05, d / 2 + 0.012, d / 2 + 0.03, zc - 0.01, zc + 0.01, METAL[0])]
    return _model("nightstand", parts)


def door(rng, wall_height=2.5):
    """A closed door in a wall: 0.80-0.95 x 2.00-2.10 m slab with casing and a handle."""
    w, h = rng.uniform(0.80, 0.95), min(rng.uniform(2.0, 2.1), wall_height - 0.15)
    col, case = tone(rng, WOOD + LAMINATE), tone(rng, LAMINATE[:1], 0.02)
    parts = [part(-w / 2, w / 2, 0.0, 0.04, 0.0, h, col),
             part(-w / 2 - 0.07, -w / 2, 0.0, 0.02, 0.0, h + 0.07, case),
             part(w / 2, w / 2 + 0.07, 0.0, 0.02, 0.0, h + 0.07, case),
             part(-w / 2, w / 2, 0.0, 0.02, h, h + 0.07, case),
             part(w / 2 - 0.12, w / 2 - 0.06, 0.04, 0.09, 0.96, 1.0, METAL[rng.integers(2)])]
    return _model("door", parts)


def window(rng, wall_height=2.5):
    """In a wall: 0.8-1.6 m wide, up to 1.5 m high, sill at 0.80-1.00 m, frame, glass, sill."""
    w, sill = rng.uniform(0.8, 1.6), rng.uniform(0.80, 1.00)
    h = min(rng.uniform(1.0, 1.5), wall_height - 0.15 - sill)
    ft, fd, frame = rng.uniform(0.04, 0.07), 0.05, tone(rng, LAMINATE[:1] + WOOD[:1], 0.03)
    top, glass = sill + h, tone(rng, ((0.70, 0.82, 0.90),), 0.03)
    parts = [part(-w / 2, -w / 2 + ft, 0, fd, sill, top, frame),
             part(w / 2 - ft, w / 2, 0, fd, sill, top, frame),
             part(-w / 2 + ft, w / 2 - ft, 0, fd, sill, sill + ft, frame),
             part(-w / 2 + ft, w / 2 - ft, 0, fd, top - ft, top, frame),
             part(-w / 2 + ft, w / 2 - ft, 0.0, 0.025, sill + ft, top - ft, glass),
             part(-w / 2 - 0.04, w / 2 + 0.04, 0, rng.uniform(0.08, 0.15), sill - 0.03, sill,
                  frame)]
    if rng.random() < 0.5:  # a mullion splits the pane
        parts.append(part(-ft / 2, ft / 2, 0.025, fd, sill + ft, top - ft, frame))
    return _model("window", parts)


def sink(rng):
    """Vanity (0.50-0.90 m wide) or pedestal sink, counter 0.82-0.88 m high, faucet at the back."""
    d, top, white = rng.uniform(0.45, 0.55), rng.uniform(0.82, 0.88), tone(rng, CERAMIC, 0.02)
    if rng.random() < 0.6:
        w, col = rng.uniform(0.50, 0.90), tone(rng, WOOD + LAMINATE)
        bw, bd = min(rng.uniform(0.35, 0.45), w - 0.1), rng.uniform(0.30, 0.38)
        parts = [part(-w / 2, w / 2, -d / 2, d / 2, 0, top - 0.03, col),
                 part(-w / 2, w / 2, -d / 2, d / 2 + 0.02, top - 0.03, top, tone(rng, LAMINATE)),
                 part(-bw / 2, bw / 2, d / 2 - bd - 0.02, d / 2 - 0.02, top,
                      top + rng.uniform(0.10, 0.14), white)]
    else:
        w = rng.uniform(0.50, 0.65)
        parts = [part(-0.1, 0.1, -d / 2, -d / 2 + 0.2, 0, top - 0.18, white),
                 part(-w / 2, w / 2, -d / 2, d / 2, top - 0.18, top, white)]
    parts.append(part(-0.02, 0.02, -d / 2 + 0.02, -d / 2 + 0.14, top, top + rng.uniform(0.2, 0.3),
                      METAL[0]))
    return _model("sink", parts)


def fridge(rng):
    """0.60-0.80 x 0.60-0.75 m, 1.6-2.0 m high, freezer door, vertical handles."""
    w, d, h = rng.uniform(0.60, 0.80), rng.uniform(0.60, 0.75), rng.uniform(1.6, 2.0)
    col = tone(rng, CERAMIC + METAL, 0.03)
    split = h * (rng.uniform(0.60, 0.70) if rng.random() < 0.5 else rng.uniform(0.30, 0.40))
    parts = [part(-w / 2, w / 2, -d / 2, d / 2, 0.0, h, col)]
    for z0, z1 in ((0.02, split - 0.005), (split + 0.005, h - 0.01)):
        zc, half = 0.5 * (z0 + z1), min(0.3, 0.35 * (z1 - z0))
        parts += [part(-w / 2 + 0.005, w / 2 - 0.005, d / 2, d / 2 + 0.02, z0, z1, shade(col, 1.0)),
                  part(w / 2 - 0.08, w / 2 - 0.05, d / 2 + 0.02, d / 2 + 0.05, zc - half, zc + half,
                       METAL[1])]
    return _model("fridge", parts)


def lamp(rng):
    """Table lamp 0.31-0.56 m high: base, stem and a shade 0.20-0.32 m across; no front."""
    r, base = rng.uniform(0.10, 0.16), tone(rng, METAL + CERAMIC + BRIGHT)
    sh, stem = rng.uniform(0.15, 0.25), rng.uniform(0.18, 0.33)
    parts = [part(-0.07, 0.07, -0.07, 0.07, 0.0, 0.03, base, "cylinder"),
             part(-0.012, 0.012, -0.012, 0.012, 0.03, 0.03 + stem, base, "cylinder"),
             part(-r, r, -r, r, stem - 0.02, stem - 0.02 + sh, tone(rng, CERAMIC + FABRIC[3:4]),
                  "cylinder")]
    return _model("lamp", parts, fronts=())


def tv(rng):
    """Flat screen 0.8-1.3 m wide (16:9), on a stand."""
    w, t, dark = rng.uniform(0.8, 1.3), rng.uniform(0.03, 0.06), tone(rng, METAL[1:], 0.03)
    z0 = rng.uniform(0.06, 0.12)
    parts = [part(-0.15 * w, 0.15 * w, -0.1, 0.1, 0.0, 0.02, dark),
             part(-0.04, 0.04, -0.03, 0.0, 0.02, z0, dark),
             part(-w / 2, w / 2, 0.0, t, z0, z0 + 0.5625 * w, dark)]
    return _model("tv", parts)


def picture(rng):
    """Framed picture 0.4-1.2 x 0.3-0.8 m, 2.5-4 cm deep (hung on a wall by the room)."""
    w, h, d, f = rng.uniform(0.4, 1.2), rng.uniform(0.3, 0.8), rng.uniform(0.025, 0.04), 0.04
    parts = [part(-w / 2, w / 2, 0.0, d - 0.005, 0.0, h, tone(rng, WOOD + METAL)),
             part(-w / 2 + f, w / 2 - f, d - 0.005, d, f, h - f, tone(rng, BRIGHT + FABRIC, 0.1))]
    return _model("picture", parts)


BUILDERS = {"chair": chair, "armchair": armchair, "sofa": sofa, "bed": bed, "table": table,
            "desk": desk, "coffee table": coffee_table, "cabinet": cabinet, "bookshelf": bookshelf,
            "toilet": toilet, "stool": stool, "nightstand": nightstand, "door": door,
            "window": window, "sink": sink, "fridge": fridge, "lamp": lamp, "tv": tv,
            "picture": picture}


def build(category: str, rng: np.random.Generator, **kwargs) -> Model:
    """Build one ``category`` piece (see :data:`BUILDERS`); kwargs: ``wall_height`` (m) for
    door / window."""
    if category not in BUILDERS:
        raise KeyError(f"no builder for {category!r}; known: {sorted(BUILDERS)}")
    return BUILDERS[category](rng, **kwargs)
