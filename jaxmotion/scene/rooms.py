"""Synthetic rooms: floor plans, furnished layouts, free floor, point clouds and meshes.

Host-side numpy. A :class:`Room` is a rectangular or L-shaped floor (3-7 m sides, floor at
z = 0) with walls, a door, 0-2 windows and 4-10 pieces of furniture placed collision-free
(see :mod:`jaxmotion.scene._layout`), plus lamps / tvs on tops and pictures above beds,
sofas and desks. Every random choice comes from one ``numpy.random.Generator`` (or a seed),
so a seed always gives the same room.

Labels: object ``i`` of ``Room.objects`` has ``id == i``; its points get instance ``i`` and
the semantic id of its category (:data:`~jaxmotion.scene.furniture.CATEGORY_IDS`). Floor and
walls are not in the object table: their points have instance -1 and semantic 2 (floor) /
1 (wall).
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from jaxmotion.scene._layout import Layout, turn
from jaxmotion.scene._parts import FACE_DIRS, Part, moved, part, parts_mesh, sample_parts
from jaxmotion.scene.furniture import CATEGORY_IDS, build
from jaxmotion.scene.io import Y_UP_TO_Z_UP, Scene

if TYPE_CHECKING:  # trimesh and scipy.ndimage are imported on use (loading a scene needs neither)
    import trimesh

ROOM_KINDS = ("bedroom", "living_room", "office", "dining_room", "bathroom")
ROOM_SHAPES = ("rect", "L")
APPROACH_DISTANCE = 0.35  # where a person stands in front of an object (m from its box)
FURNITURE_RANGE = (4, 10)  # floor-standing pieces per room
WALL_THICKNESS = 0.1
_WALL_RGB = ((0.88, 0.86, 0.82), (0.80, 0.84, 0.86), (0.90, 0.88, 0.78), (0.78, 0.80, 0.76))
_FLOOR_RGB = ((0.55, 0.40, 0.26), (0.70, 0.62, 0.50), (0.45, 0.45, 0.47), (0.80, 0.78, 0.74))


@dataclasses.dataclass(frozen=True)
class Room:
    """A furnished room in metres, z-up, floor at z = 0.

    Attributes:
      name: scene name (unique per seed in practice).
      kind: one of :data:`ROOM_KINDS`; shape: ``"rect"`` or ``"L"``.
      floor_rects: disjoint (xmin, ymin, xmax, ymax) rectangles whose union is the floor.
      wall_height: m.
      walls: (x0, y0, x1, y1) wall segments, counter-clockwise: the room is on their left.
      objects: object table, ``objects[i]["id"] == i``; dicts with ``category``,
        ``bbox_min`` / ``bbox_max`` (world, axis-aligned), ``surface_height`` (world z of the
        sit / lie surface: seats, beds), ``front`` [fx, fy, 0] (unit, the way a seat faces
        or a door / cabinet opens), ``head`` [3] (beds: from the middle toward the
        headboard) and ``parent`` (lamp / tv: the object it stands on; picture: the one it
        hangs above).
      parts: labelled boxes / cylinders of floor, walls and objects, for sampling / meshing.
    """

    name: str
    kind: str
    shape: str
    floor_rects: tuple[tuple[float, float, float, float], ...]
    wall_height: float
    walls: tuple[tuple[float, float, float, float], ...]
    objects: tuple[dict, ...]
    parts: tuple[Part, ...]

    def object(self, object_id: int) -> dict:
        """The object-table entry with ``id == object_id`` (a copy)."""
        if not 0 <= object_id < len(self.objects):
            raise KeyError(f"room {self.name!r} has no object {object_id!r}; "
                           f"valid ids: 0..{len(self.objects) - 1}")
        return dict(self.objects[object_id])

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """xy bounds of the floor: (lo [2], hi [2]) m."""
        r = np.array(self.floor_rects)
        return r[:, :2].min(0), r[:, 2:].max(0)


def _as_rng(rng_or_seed) -> np.random.Generator:
    if isinstance(rng_or_seed, np.random.Generator):
        return rng_or_seed
    if rng_or_seed is None or isinstance(rng_or_seed, bool):
        raise TypeError("pass a numpy.random.Generator or an int seed (no hidden randomness)")
    return np.random.default_rng(rng_or_seed)


def _floor_plan(rng, shape):
    """(rects, counter-clockwise polygon) of a 3-7 m rectangle or a 4-7 m L-shape."""
    if shape == "rect":
        w, d = rng.uniform(3.0, 7.0, 2)
        return [(0.0, 0.0, w, d)], [(0, 0), (w, 0), (w, d), (0, d)]
    w, d = rng.uniform(4.0, 7.0, 2)
    cw, cd = rng.uniform(1.5, w - 2.2), rng.uniform(1.5, d - 2.2)  # the cut-out corner
    rects = [(0.0, 0.0, w, d - cd), (0.0, d - cd, w - cw, d)]
    poly = [(0, 0), (w, 0), (w, d - cd), (w - cw, d - cd), (w - cw, d), (0, d)]
    fx, fy = rng.random() < 0.5, rng.random() < 0.5  # mirror so any corner can be cut
    mx = (lambda x: w - x) if fx else (lambda x: x)
    my = (lambda y: d - y) if fy else (lambda y: y)
    rects = [(min(mx(a), mx(c)), min(my(b), my(e)), max(mx(a), mx(c)), max(my(b), my(e)))
             for a, b, c, e in rects]
    poly = [(mx(x), my(y)) for x, y in poly]
    return rects, poly[::-1] if fx != fy else poly


def _shell_parts(rng, rects, walls, height):
    """Floor slabs (only the top visible) and walls (only the inner face visible)."""
    floor = np.asarray(_FLOOR_RGB[rng.integers(len(_FLOOR_RGB))]) * rng.uniform(0.9, 1.1)
    wall = np.asarray(_WALL_RGB[rng.integers(len(_WALL_RGB))]) * rng.uniform(0.95, 1.05)
    parts = [dataclasses.replace(part(r[0], r[2], r[1], r[3], -0.02, 0.0, floor),
                                 semantic=CATEGORY_IDS["floor"], faces=(False,) * 5 + (True,))
             for r in rects]
    for x0, y0, x1, y1 in walls:
        n = np.array([-(y1 - y0), x1 - x0]) / np.hypot(x1 - x0, y1 - y0)  # inward
        ox, oy = -WALL_THICKNESS * n
        faces = [bool(np.allclose(f, [*n, 0])) for f in FACE_DIRS]
        p = part(x0, x1 + ox, y0, y1 + oy, 0.0, height, wall)
        parts.append(dataclasses.replace(p, semantic=CATEGORY_IDS["wall"], faces=tuple(faces)))
    return parts


_FILLERS = {"bedroom": ("cabinet", "bookshelf", "chair", "stool", "armchair", "nightstand"),
            "living_room": ("armchair", "stool", "bookshelf", "cabinet", "chair"),
            "office": ("chair", "bookshelf", "cabinet", "stool", "armchair"),
            "dining_room": ("chair", "stool", "cabinet", "chair"),
            "bathroom": ("cabinet", "stool", "sink")}
_AGAINST_WALL = ("cabinet", "bookshelf", "nightstand", "sink", "fridge", "desk", "sofa", "bed")


def _furnish(lay: Layout, kind: str) -> bool:
    """Run the room kind's recipe; False when its key piece does not fit."""
    rng = lay.rng

    def put(category, how, *args, **kwargs):
        full = lay.furniture_count() >= FURNITURE_RANGE[1]
        if full and category not in ("lamp", "tv", "picture"):
            return None
        return how(build(category, rng), *args, **kwargs)

    def chance(p):
        return rng.random() < p

    def dress(host, lamp=0.0, tv=0.0, pic=0.0):  # small things on / above a wall piece
        if host is not None and chance(lamp):
            put("lamp", lay.on_top, host)
        if host is not None and host.hi[2] < 1.1 and chance(tv):
            put("tv", lay.on_top, host)
        if host is not None and host.wall is not None and chance(pic):
            put("picture", lay.above, host)

    def desk_group():
        desk = put("desk", lay.on_wall)
        if desk is not None:
            put("chair", lay.facing, desk, sides=[desk.front])
            dress(desk, lamp=0.35, pic=0.25)

    def table_group(lo, hi):
        table = put("table", lay.free)
        for _ in range(int(rng.integers(lo, hi + 1)) if table is not None else 0):
            put("chair", lay.facing, table)
        return table

    def sofa_group():
        sofa = put("sofa", lay.on_wall)
        if sofa is not None:
            coffee = put("coffee table", lay.in_front, sofa) if chance(0.8) else None
            for _ in range(int(rng.integers(0, 3)) if coffee is not None else 0):
                put("armchair", lay.facing, coffee)
            dress(sofa, pic=0.5)
        return sofa

    def extras(*spec):  # (category, probability, placement) in a random order
        for i in rng.permutation(len(spec)):
            category, p, how = spec[i]
            if chance(p):
                host = put(category, lay.on_wall if how == "wall" else lay.free)
                if category == "cabinet":
                    dress(host, tv=0.35)

    if kind == "bedroom":
        head_to_wall = chance(0.7)
        bed = put("bed", lay.on_wall, back=(0.0, -1.0) if head_to_wall else (1.0, 0.0))
        if bed is None:
            return False
        for sign in (-1, 1) if head_to_wall else ():
            if chance(0.6):
                dress(put("nightstand", lay.beside, bed, sign), lamp=0.6)
        dress(bed, pic=0.4)
        if chance(0.4):
            desk_group()
        extras(("cabinet", 0.6, "wall"), ("cabinet", 0.3, "wall"), ("bookshelf", 0.4, "wall"),
               ("armchair", 0.3, "free"), ("chair", 0.3, "free"), ("stool", 0.2, "free"))
    elif kind == "living_room":
        if sofa_group() is None:
            return False
        if chance(0.3):
            table_group(2, 4)
        extras(("cabinet", 0.7, "wall"), ("bookshelf", 0.5, "wall"), ("bookshelf", 0.2, "wall"),
               ("stool", 0.3, "free"), ("armchair", 0.2, "free"), ("chair", 0.2, "free"))
    elif kind == "office":
        desk_group()
        if chance(0.5):
            desk_group()
        if chance(0.25):
            table_group(2, 4)
        if chance(0.2):
            sofa_group()
        extras(("bookshelf", 0.6, "wall"), ("bookshelf", 0.3, "wall"), ("cabinet", 0.5, "wall"),
               ("cabinet", 0.2, "wall"), ("armchair", 0.3, "free"), ("stool", 0.2, "free"))
    elif kind == "dining_room":
        if table_group(2, 6) is None:
            return False
        extras(("fridge", 0.6, "wall"), ("sink", 0.6, "wall"), ("cabinet", 0.6, "wall"),
               ("cabinet", 0.3, "wall"), ("stool", 0.4, "free"), ("stool", 0.2, "free"),
               ("bookshelf", 0.3, "wall"), ("armchair", 0.2, "free"))
    else:  # bathroom
        if put("toilet", lay.on_wall) is None:
            return False
        extras(("sink", 1.0, "wall"), ("sink", 0.3, "wall"), ("cabinet", 0.9, "wall"),
               ("cabinet", 0.4, "wall"), ("stool", 0.7, "free"), ("chair", 0.2, "free"))
    target = int(rng.integers(FURNITURE_RANGE[0], FURNITURE_RANGE[1] + 1))
    fillers = _FILLERS[kind]
    for _ in range(2 * target):  # top up toward a random count, as space allows
        if lay.furniture_count() >= target:
            break
        category = fillers[rng.integers(len(fillers))]
        host = put(category, lay.on_wall if category in _AGAINST_WALL else lay.free)
        dress(host, lamp=0.3 if category == "nightstand" else 0.0,
              tv=0.3 if category == "cabinet" else 0.0)
    return lay.furniture_count() >= FURNITURE_RANGE[0]


def _to_room(lay: Layout, name, kind, shape, shell) -> Room:
    objects, parts = [], list(shell)
    for it in lay.items:
        m, sem = it.model, CATEGORY_IDS[it.category]
        obj = dict(id=it.index, category=it.category, bbox_min=it.lo.tolist(),
                   bbox_max=it.hi.tolist())
        if m.surface_height is not None:
            obj["surface_height"] = float(m.surface_height + it.t[2])
        if it.front is not None:
            obj["front"] = [float(it.front[0]), float(it.front[1]), 0.0]
        if it.category == "bed":
            obj["head"] = [*turn((0.0, -1.0), it.k).tolist(), 0.0]
        if it.parent is not None:
            obj["parent"] = it.parent
        objects.append(obj)
        parts += [dataclasses.replace(moved(p, it.k, it.t), semantic=sem, instance=it.index)
                  for p in m.parts]
    return Room(name, kind, shape, tuple(lay.rects), float(lay.height), tuple(lay.walls),
                tuple(objects), tuple(parts))


def sample_room(rng_or_seed, *, kind: str | None = None, shape: str | None = None,
                max_tries: int = 200) -> Room:
    """A random furnished room (see the module docstring).

    Args:
      rng_or_seed: ``numpy.random.Generator`` (advanced in place) or int seed.
      kind: one of :data:`ROOM_KINDS` (random when None); shape: ``"rect"`` / ``"L"``.
      max_tries: layouts to try before giving up (a layout is redrawn when its key piece
        does not fit or the floor is not navigable, see :func:`is_navigable`).
    """
    rng = _as_rng(rng_or_seed)
    for option, allowed in ((kind, ROOM_KINDS), (shape, ROOM_SHAPES)):
        if option is not None and option not in allowed:
            raise ValueError(f"unknown option {option!r}; choose from {allowed}")
    for _ in range(max_tries):
        k = kind or ROOM_KINDS[rng.integers(len(ROOM_KINDS))]
        s = shape or ("L" if rng.random() < 0.3 else "rect")
        rects, poly = _floor_plan(rng, s)
        walls = [(*poly[i], *poly[(i + 1) % len(poly)]) for i in range(len(poly))]
        walls = [tuple(float(v) for v in w) for w in walls]
        height = float(rng.uniform(2.5, 3.0))
        lay = Layout(rng, [tuple(map(float, r)) for r in rects], walls, height)
        if lay.on_wall(build("door", rng, wall_height=height), gap=0.0) is None:
            continue
        for _ in range(int(rng.integers(0, 2 if k == "bathroom" else 3))):
            lay.on_wall(build("window", rng, wall_height=height), gap=0.0)
        shell = _shell_parts(rng, lay.rects, walls, height)
        if _furnish(lay, k):
            room = _to_room(lay, f"{k}_{int(rng.integers(1 << 32)):08x}", k, s, shell)
            if is_navigable(room):
                return room
    raise RuntimeError(f"no valid {kind or 'random'} room in {max_tries} tries")


def approach_points(room: Room, object_id: int, distance: float = APPROACH_DISTANCE):
    """Where a person would stand to reach an object: [K, 2] xy points (m).

    ``distance`` in front of the middle of its front face when it has a ``front``
    (K = 1), else in front of each of its 4 sides (K = 4); a lamp / tv / picture uses
    its ``parent``'s points.
    """
    obj = room.object(object_id)
    if "parent" in obj:
        return approach_points(room, obj["parent"], distance)
    lo, hi = np.asarray(obj["bbox_min"][:2]), np.asarray(obj["bbox_max"][:2])
    c, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    dirs = [np.asarray(obj["front"][:2])] if "front" in obj else list(np.eye(2)) + list(-np.eye(2))
    return np.array([c + d * (np.abs(d) @ half + distance) for d in dirs])


def free_space_grid(room: Room, resolution: float = 0.05, clearance: float = 0.2):
    """Floor occupancy grid: (free [H, W] bool, origin [2] xy m, resolution m).

    Cell ``[iy, ix]`` has its centre at ``origin + ((ix + 0.5), (iy + 0.5)) * resolution``
    and is free when it lies on the floor, at least ``clearance`` (a body radius) from the
    walls and farther than ``clearance`` in xy from every object's box.
    """
    lo, hi = room.bounds()
    shape = np.ceil((hi - lo) / resolution).astype(int)  # (W, H)
    xs = lo[0] + (np.arange(shape[0]) + 0.5) * resolution
    ys = lo[1] + (np.arange(shape[1]) + 0.5) * resolution
    x, y = np.meshgrid(xs, ys)  # [H, W]
    floor = np.zeros(x.shape, bool)
    for x0, y0, x1, y1 in room.floor_rects:
        floor |= (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
    from scipy import ndimage

    to_wall = ndimage.distance_transform_edt(np.pad(floor, 1))[1:-1, 1:-1] * resolution
    free = floor & (to_wall - resolution / 2 >= clearance)
    for obj in room.objects:
        (bx0, by0), (bx1, by1) = obj["bbox_min"][:2], obj["bbox_max"][:2]
        dx = np.maximum(np.maximum(bx0 - x, x - bx1), 0.0)
        dy = np.maximum(np.maximum(by0 - y, y - by1), 0.0)
        free &= np.hypot(dx, dy) > clearance
    return free, lo.astype(float), float(resolution)


def is_navigable(room: Room, resolution: float = 0.05, clearance: float = 0.2) -> bool:
    """True when one 4-connected free component of :func:`free_space_grid` holds the door's
    approach point and, for every object, at least one of its :func:`approach_points`."""
    free, origin, res = free_space_grid(room, resolution, clearance)
    from scipy import ndimage

    labels, _ = ndimage.label(free)

    def component(points):
        cells = np.floor((points - origin) / res).astype(int)
        ok = (cells >= 0).all(1) & (cells[:, 0] < free.shape[1]) & (cells[:, 1] < free.shape[0])
        return {int(labels[iy, ix]) for ix, iy in cells[ok]} - {0}

    doors = [o["id"] for o in room.objects if o["category"] == "door"]
    main = component(approach_points(room, doors[0])) if doors else set()
    if len(main) != 1:
        return False
    return all(main & component(approach_points(room, o["id"])) for o in room.objects)


def room_to_scene(room: Room, num_points: int, rng) -> Scene:
    """ScanNet-like point cloud of a room: ``num_points`` area-weighted samples of the
    visible surfaces with outward normals, noisy colours in [0, 1], semantic and instance
    ids (floor / walls: instance -1) and the room's object table. ``rng``: Generator or seed.
    """
    arrays = sample_parts(room.parts, int(num_points), _as_rng(rng))
    return Scene(**arrays, objects=room.objects, name=room.name)


def room_to_mesh(room: Room, *, up: str = "z") -> trimesh.Trimesh:
    """Triangle mesh of a room's visible surfaces with RGBA vertex colours.

    ``up="z"`` keeps the jaxmotion frame (for PLY / OBJ); ``up="y"`` turns it y-up, as
    glTF / GLB expect (``load_scene`` turns .glb files back to z-up). Export with
    ``mesh.export("room.ply")`` or ``mesh.export("room.glb")``.
    """
    mesh = parts_mesh(room.parts)
    if up == "y":
        mesh.vertices = np.asarray(mesh.vertices) @ Y_UP_TO_Z_UP  # the inverse rotation
    elif up != "z":
        raise ValueError(f"up must be 'z' or 'y', got {up!r}")
    return mesh
