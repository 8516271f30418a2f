"""The software renderer (jaxmotion.render): rasterizer against brute force, bodies, clips, CLI."""

from __future__ import annotations

import numpy as np
import pytest

from jaxmotion.render import raster

# --------------------------------------------------------------------------- rasterizer


def _brute_triangles(xy, z, faces, width, height, cull_back):
    """Per pixel, per triangle: nearest depth and its face (−1: none), by plain loops over
    pixel centres in float64; ``edge [H, W]`` marks centres within 1e-4 of an edge."""
    depth = np.full((height, width), np.inf)
    face = np.full((height, width), -1)
    edge = np.zeros((height, width), bool)
    for f, (a, b, c) in enumerate(faces):
        (xa, ya), (xb, yb), (xc, yc) = xy[a], xy[b], xy[c]
        area2 = (xb - xa) * (yc - ya) - (xc - xa) * (yb - ya)
        if area2 == 0 or (cull_back and area2 > 0):
            continue
        for row in range(height):
            for col in range(width):
                px, py = col + 0.5, row + 0.5
                w0 = ((xc - xb) * (py - yb) - (yc - yb) * (px - xb)) / area2
                w1 = ((xa - xc) * (py - yc) - (ya - yc) * (px - xc)) / area2
                w2 = 1.0 - w0 - w1
                if min(w0, w1, w2) < -1e-4:
                    continue
                if min(abs(w0), abs(w1), abs(w2)) < 1e-4:
                    edge[row, col] = True
                if min(w0, w1, w2) < 0:
                    continue
                d = 1.0 / (w0 / z[a] + w1 / z[b] + w2 / z[c])
                if d < depth[row, col]:
                    depth[row, col], face[row, col] = d, f
    return depth, face, edge


@pytest.mark.parametrize("cull_back", [False, True])
def test_triangles_match_a_brute_force_loop(cull_back):
    rng = np.random.default_rng(0)
    width, height = 40, 30
    # small (sub-pixel to a few pixels), medium and large triangles, both windings,
    # overlapping at different depths, some reaching outside the picture
    centres = rng.uniform([-5, -5], [width + 5, height + 5], size=(24, 2))
    sizes = np.repeat([0.7, 2.5, 6.0, 18.0], 6)
    xy = (centres[:, None] + rng.normal(size=(24, 3, 2)) * sizes[:, None, None]).reshape(-1, 2)
    z = rng.uniform(1.0, 5.0, size=len(xy))
    faces = np.arange(len(xy)).reshape(-1, 3)
    frags = raster.raster_triangles(xy, z, faces, width, height, cull_back=cull_back)
    buf = raster.resolve(np.full(width * height, raster.EMPTY_KEY), frags)
    got_depth = raster.depth_of_keys(buf).reshape(height, width)
    got_face = raster.id_of_keys(buf).reshape(height, width)
    want_depth, want_face, edge = _brute_triangles(xy, z, faces, width, height, cull_back)
    clear = ~edge  # a centre exactly on an edge may go either way
    assert (got_face >= 0).sum() > 200  # the test covers something
    np.testing.assert_array_equal(got_face[clear], want_face[clear])
    covered = clear & (want_face >= 0)
    np.testing.assert_allclose(got_depth[covered], want_depth[covered], rtol=1e-5)
    assert np.all(np.isinf(got_depth[clear & (want_face < 0)]))


def test_a_closed_mesh_leaves_no_holes():
    """A square cut into many tiny triangles covers every pixel centre inside it once."""
    n = 30  # 30 × 30 cells of 0.8 px, two triangles each
    g = np.stack(np.meshgrid(np.arange(n + 1), np.arange(n + 1)), -1).reshape(-1, 2) * 0.8 + 3.3
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    faces = np.concatenate([np.stack([a, c, b], -1), np.stack([b, c, d], -1)]).reshape(-1, 3)
    frags = raster.raster_triangles(g.astype(float), np.full(len(g), 2.0), faces, 32, 32,
                                    cull_back=False)
    covered = np.zeros(32 * 32, bool)
    covered[frags.pix] = True
    cx = np.arange(32) + 0.5
    inside = ((cx >= 3.3) & (cx <= 3.3 + 0.8 * n))
    want = (inside[:, None] & inside[None, :]).reshape(-1)
    np.testing.assert_array_equal(covered, want)


def test_back_faces_are_culled():
    xy = np.array([[2.0, 2.0], [2.0, 12.0], [12.0, 2.0]])  # clockwise on screen (y down)
    z = np.ones(3)
    front = raster.raster_triangles(xy, z, np.array([[0, 1, 2]]), 16, 16)
    back = raster.raster_triangles(xy, z, np.array([[0, 2, 1]]), 16, 16)
    assert len(front.pix) > 20 and len(back.pix) == 0


def test_keys_order_by_depth_then_id():
    k = raster.keys(np.array([2.0, 1.0, 1.0, 0.5]), np.array([0, 7, 3, 9]))
    buf = raster.resolve(np.full(2, raster.EMPTY_KEY), raster.Fragments(np.array([0, 0, 0, 1]), k))
    assert raster.id_of_keys(buf).tolist() == [3, 9]
    assert raster.depth_of_keys(buf).tolist() == [1.0, 0.5]
    assert raster.id_of_keys(np.array([raster.EMPTY_KEY])).tolist() == [-1]


def test_surfels_cover_their_ellipse_with_plane_depths():
    focal, cx, cy, w, h = 50.0, 20.0, 20.0, 40, 40
    centre = np.array([[0.0, 0.0, 2.0], [0.6, 0.0, 3.0]])
    tilt = np.array([0.0, np.sin(1.0), -np.cos(1.0)])  # a disc turned 57° about x
    normal = np.array([[0.0, 0.0, 0.0], tilt])  # the first faces the camera (zero normal)
    radius = np.array([0.3, 0.5])
    frags = raster.raster_surfels(centre, normal, radius, focal, cx, cy, w, h)
    ids = raster.id_of_keys(frags.key)
    depth = raster.depth_of_keys(frags.key)
    col, row = frags.pix % w, frags.pix // w
    rx, ry = (col + 0.5 - cx) / focal, (row + 0.5 - cy) / focal
    # facing disc: a circle of radius R f / z = 7.5 px around (20, 20), depth 2
    a = ids == 0
    r = np.hypot(col[a] + 0.5 - 20, row[a] + 0.5 - 20)
    assert r.max() <= 7.5 + 0.6 and a.sum() == pytest.approx(np.pi * 7.5**2, rel=0.12)
    np.testing.assert_allclose(depth[a], 2.0)
    # slanted disc: each covered pixel's depth is where its ray meets the disc's plane, and
    # that meeting point lies within the radius (0.5 m, with the ~0.5 px widening allowed)
    b = ids == 1
    t = (tilt @ centre[1]) / (tilt[0] * rx[b] + tilt[1] * ry[b] + tilt[2])
    np.testing.assert_allclose(depth[b], t, rtol=0.03)
    hit = np.stack([t * rx[b], t * ry[b], t], 1)
    assert np.linalg.norm(hit - centre[1], axis=1).max() < 0.5 + 3 * 0.5 * 3.0 / focal
    assert b.sum() > 0.6 * np.pi * (0.5 * focal / 3.0) ** 2 * np.cos(1.0)


# --------------------------------------------------------------------------- compiled kernels


def _random_mesh(rng, n_tri=300, width=48, height=40):
    """Small triangles scattered over a picture, at random depths (overlapping, both
    windings), as body triangles are: pixel coordinates, depths and faces."""
    centre = rng.uniform([-4, -4], [width + 4, height + 4], (n_tri, 1, 2))
    xy = (centre + rng.normal(scale=rng.choice([0.6, 2.0, 6.0], (n_tri, 1, 1)),
                              size=(n_tri, 3, 2))).reshape(-1, 2)
    z = np.repeat(rng.uniform(1.0, 3.0, n_tri), 3) + rng.normal(scale=0.05, size=3 * n_tri)
    faces = np.arange(3 * n_tri).reshape(-1, 3)
    return xy, z, faces


@pytest.mark.parametrize("seed", [0, 1])
def test_compiled_triangles_are_the_numpy_rasterizers(seed):
    """kernels.raster_triangles covers the pixels raster_triangles + resolve cover, with the
    same winning triangle and depth, over a background it must beat (ties on depth: the
    smaller id)."""
    from jaxmotion.render import kernels

    rng = np.random.default_rng(seed)
    w, h = 48, 40
    xy, z, faces = _random_mesh(rng)
    z[:9] = 2.0  # a few exact ties in depth
    background = np.where(rng.random((h, w)) < 0.5, np.inf,
                          rng.uniform(1.5, 2.5, (h, w))).astype(np.float32)
    bg_id = 0xFFFF_FFFD
    buf = raster.keys(background.reshape(-1), np.full(w * h, bg_id))
    raster.resolve(buf, raster.raster_triangles(xy, z, faces, w, h, id_offset=5))
    depth, ids = background.copy(), np.full((h, w), bg_id, np.int64)
    kernels.raster_triangles(xy[:, 0].copy(), xy[:, 1].copy(), z, faces, 0, 5, depth, ids)
    np.testing.assert_array_equal(ids.reshape(-1), raster.id_of_keys(buf))
    np.testing.assert_array_equal(depth.reshape(-1), raster.depth_of_keys(buf))
    assert (ids < bg_id).sum() > 200


def test_compiled_surfels_are_the_numpy_rasterizers():
    """kernels.raster_surfels: raster_surfels + resolve's pixels and winners; depths to the
    float32 rounding of a 2 × 2 solve written out rather than LAPACK's."""
    from jaxmotion.render import kernels

    rng = np.random.default_rng(4)
    n, w, h, focal = 400, 64, 48, 60.0
    centre = np.c_[rng.uniform(-1.2, 1.2, (n, 2)), rng.uniform(1.5, 4.0, n)]
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    normal[::7] = 0.0  # unknown: facing the camera
    radius = rng.uniform(0.01, 0.12, n)
    buf = np.full(w * h, raster.EMPTY_KEY)
    raster.resolve(buf, raster.raster_surfels(centre, normal, radius, focal, 32.0, 24.0, w, h))
    depth, ids = np.full((h, w), np.inf, np.float32), np.full((h, w), -1, np.int64)
    kernels.raster_surfels(centre, normal, radius, focal, 32.0, 24.0, depth, ids)
    want_ids, want_depth = raster.id_of_keys(buf), raster.depth_of_keys(buf)
    assert (ids.reshape(-1) != want_ids).mean() < 0.002  # a rounding may flip a near-tie
    same = ids.reshape(-1) == want_ids
    np.testing.assert_allclose(depth.reshape(-1)[same], want_depth[same], rtol=1e-6)
    assert (want_ids >= 0).mean() > 0.3


@pytest.mark.parametrize("layout", ["room", "clustered", "sparse"])
def test_splat_radii_are_the_brute_force_neighbour_distances(layout):
    """kernels.kth_distances: each query's distance to its 6th-nearest point (itself the 0th;
    duplicates count), by a full sort of every distance; beyond the cap it may stop at the cap
    (the radii are clipped there)."""
    from jaxmotion.render import kernels

    rng = np.random.default_rng(5)
    if layout == "room":  # a floor, a wall and a box's top, as a scan samples them
        pts = np.r_[np.c_[rng.uniform(0, 1.5, (900, 2)), np.zeros(900)],
                    np.c_[rng.uniform(0, 1.5, 300), np.zeros(300), rng.uniform(0, 0.8, 300)],
                    np.c_[rng.uniform(0.5, 1.0, (200, 2)), np.full(200, 0.45)]]
    elif layout == "clustered":  # dense clumps far apart, and exact duplicates
        pts = np.r_[rng.normal(0, 0.01, (300, 3)), rng.normal(5, 0.02, (300, 3))]
        pts = np.r_[pts, pts[:40]]
    else:  # neighbours mostly farther than the cap, over a wide box
        pts = rng.uniform(-20, 20, (400, 3))
    queries = rng.choice(len(pts), 150, replace=False)
    cap = 0.10
    got = kernels.kth_distances(pts, queries, 6, cap)
    d = np.sort(np.linalg.norm(pts[queries, None] - pts[None], axis=-1), axis=1)[:, 6]
    near = d < cap
    np.testing.assert_allclose(got[near], d[near], rtol=1e-12, atol=0)
    assert np.all(got[~near] >= cap - 1e-12)
    np.testing.assert_allclose(np.minimum(got, cap), np.minimum(d, cap), rtol=1e-12)
    assert (~near).all() if layout == "sparse" else near.mean() > 0.6


def test_shadow_filters_are_scipys():
    """The shadow map's blur and minimum (scene.gaussian_filter, scene.minimum_filter) give
    ``scipy.ndimage``'s answers (zero outside; edges extended)."""
    from scipy import ndimage

    from jaxmotion.render.scene import gaussian_filter, minimum_filter

    rng = np.random.default_rng(6)
    for shape, sigma in (((61, 47), 2.25), ((30, 41), 3.5), ((4, 9), 3.5)):
        a = (rng.random(shape) > 0.8).astype(np.float32)
        np.testing.assert_allclose(gaussian_filter(a, sigma),
                                   ndimage.gaussian_filter(a, sigma, mode="constant"),
                                   rtol=1e-6, atol=1e-7)
        low = np.where(rng.random(shape) > 0.6, rng.random(shape), np.inf).astype(np.float32)
        np.testing.assert_array_equal(minimum_filter(low, 5),
                                      ndimage.minimum_filter(low, size=5, mode="nearest"))


def test_compiled_shading_and_compositing_are_the_numpy_formulas():
    """vertex_colours: area-weighted vertex normals (the exporters' vertex_normals) lit by
    the body's lights; compose: each pixel the mean of its 2 × 2 samples, a body sample the
    vertex colours interpolated with raster.triangle_barycentrics, others the room's."""
    from jaxmotion.export._common import vertex_normals
    from jaxmotion.render import kernels

    rng = np.random.default_rng(5)
    verts = rng.normal(size=(60, 3)).astype(np.float32)
    faces = np.stack([rng.choice(59, 3, replace=False) for _ in range(90)])  # 59: no face
    base = np.array([0.5, 0.6, 0.9])
    light, view = np.array([0.3, -0.4, 0.866]), np.array([0.0, -1.0, 0.0])
    half = (light + view) / np.linalg.norm(light + view)
    got = np.empty((60, 3), np.float32)
    kernels.vertex_colours(verts, faces, base, light, view, half, got)
    n = vertex_normals(verts, faces).astype(np.float64)
    dots = n @ np.stack([light, view, half]).T
    lit = 0.30 + 0.20 * (0.5 + 0.5 * n[:, 2]) + 0.55 * np.maximum(dots[:, 0], 0)
    extra = 0.10 * (1 - np.clip(dots[:, 1], 0, 1)) ** 3 + 0.12 * np.maximum(dots[:, 2], 0) ** 40
    want = np.clip(base * lit[:, None] + extra[:, None], 0, 1)
    np.testing.assert_allclose(got, want, atol=2e-6)
    np.testing.assert_allclose(got[59], base * 0.40 + 0.10, atol=1e-6)  # no face: no normal

    w, h = 40, 32  # samples (2× a 20 × 16 picture)
    xy, z, tri = _random_mesh(rng, 120, w, h)
    colours = rng.random((len(xy), 3)).astype(np.float32)
    depth, ids = np.full((h, w), np.inf, np.float32), np.full((h, w), 1 << 40, np.int64)
    kernels.raster_triangles(xy[:, 0].copy(), xy[:, 1].copy(), z, tri, 0, 0, depth, ids)
    room = rng.random((h // 2, w // 2, 3)).astype(np.float32)
    out = np.empty_like(room)
    kernels.compose(ids, xy[:, 0].copy(), xy[:, 1].copy(), z, tri, len(tri), len(xy), colours,
                    room, 2, out)
    samples = np.repeat(np.repeat(room, 2, 0), 2, 1).reshape(-1, 3)
    body = np.flatnonzero(ids.reshape(-1) < len(tri))
    face = ids.reshape(-1)[body]
    bary = raster.triangle_barycentrics(xy, z, tri, face, body % w, body // w)
    samples[body] = (bary[:, :, None] * colours[tri[face]]).sum(1)
    want = samples.reshape(h // 2, 2, w // 2, 2, 3).mean((1, 3))
    np.testing.assert_allclose(out, want, atol=1e-6)
    assert len(body) > 100


# --------------------------------------------------------------------------- bodies


def _standing(t: int, walk: float = 0.0, k: int = 1, seed: int = 0):
    """SMPL-X parameters of ``k`` bodies standing (walking ``walk`` metres along x over ``t``
    frames), feet on the floor, and their joints."""
    from jaxmotion.io.motion import smplx_joints_host

    rng = np.random.default_rng(seed)
    go = np.tile([np.pi / 2, 0.0, 0.0], (k, t, 1))
    bp = rng.normal(size=(k, t, 21, 3)) * 0.05
    tr = np.zeros((k, t, 3))
    tr[..., 0] = np.linspace(0.0, walk, t)
    tr[:, :, 1] = np.arange(k)[:, None] * 0.8
    joints = np.stack([smplx_joints_host(go[s], bp[s], tr[s]) for s in range(k)])
    lift = -joints[..., 2].min() + 0.08
    tr[..., 2] += lift
    joints[..., 2] += lift
    return {"global_orient": go, "body_pose": bp, "transl": tr,
            "betas": np.zeros((k, 10))}, joints


def _room(n: int = 4000, seed: int = 1):
    """A floor, a back wall and a box 'chair' (object 1) as points with normals."""
    from jaxmotion.scene import Scene

    rng = np.random.default_rng(seed)
    floor = np.c_[rng.uniform(-2, 3, (n, 2)), np.zeros(n)]
    wall = np.c_[rng.uniform(-2, 3, n // 2), np.full(n // 2, 2.0), rng.uniform(0, 2, n // 2)]
    box = rng.uniform([0.6, 0.8, 0.0], [1.1, 1.3, 0.45], (n // 4, 3))
    box[:, 2] = 0.45  # its seat
    xyz = np.concatenate([floor, wall, box])
    normal = np.concatenate([np.tile([0, 0, 1.0], (n, 1)), np.tile([0, -1.0, 0], (n // 2, 1)),
                             np.tile([0, 0, 1.0], (n // 4, 1))])
    rgb = np.concatenate([np.tile([0.6, 0.5, 0.4], (n, 1)), np.tile([0.8, 0.8, 0.8], (n // 2, 1)),
                          np.tile([0.5, 0.2, 0.2], (n // 4, 1))])
    instance = np.r_[np.full(n + n // 2, -1), np.full(n // 4, 1)]
    objects = [{"id": 1, "category": "chair", "bbox_min": [0.6, 0.8, 0.0],
                "bbox_max": [1.1, 1.3, 0.45]}]
    return Scene(xyz, rgb, normal, instance=instance, objects=objects, name="test room")


def test_host_skinning_matches_body_forward():
    from jaxmotion.body import body_forward, load_mannequin
    from jaxmotion.render import Bodies

    p, _ = _standing(3, k=2)
    p["betas"][1, :3] = [0.5, -0.3, 0.2]
    bodies = Bodies.from_smplx(p["global_orient"], p["body_pose"], p["transl"], p["betas"],
                               model=load_mannequin())
    for s in range(2):
        want = np.asarray(body_forward(load_mannequin(), p["global_orient"][s, 2],
                                       p["body_pose"][s, 2], p["transl"][s, 2],
                                       p["betas"][s]).vertices)
        np.testing.assert_allclose(bodies.frame(2)[s], want, atol=2e-5)
    assert bodies.frame(2).shape == (2, load_mannequin().num_vertices, 3)


def _clip(size=(96, 72), t=4, k=1, walk=0.0, **options):
    from jaxmotion.render import Bodies, Clip

    p, joints = _standing(t, walk, k)
    room = _room()
    bodies = Bodies.from_smplx(p["global_orient"], p["body_pose"], p["transl"], p["betas"])
    return Clip(bodies, joints, 30.0, room.xyz, room.rgb, scene_normal=room.normal,
                highlight=room.instance == 1, instance=room.instance, text="stand",
                size=size, **options)


def test_a_frame_shows_the_body_where_its_vertices_project():
    from jaxmotion.render.frames import body_colour

    clip = _clip(size=(160, 120))
    img = clip.draw(2).astype(float) / 255
    assert img.shape == (120, 160, 3)
    xy, _ = clip.cameras[2].project(clip.bodies.frame(2)[0])
    col, row = np.floor(xy).astype(int).T
    assert col.min() > 0 and col.max() < 159 and row.min() > 0 and row.max() < 119

    def bluish(c):  # lit or in shade; the room is brown, grey, white and amber
        return c[..., 2] > 1.3 * c[..., 0] + 0.02

    assert bluish(body_colour(0)) and bluish(0.3 * body_colour(0))
    blue = bluish(img)
    near = blue.copy()  # silhouette pixels are blends of body and room: next to blue ones
    near[1:] |= blue[:-1]
    near[:-1] |= blue[1:]
    near[:, 1:] |= blue[:, :-1]
    near[:, :-1] |= blue[:, 1:]
    assert blue[row, col].mean() > 0.75
    assert near[row, col].mean() > 0.98  # fingertips are thinner than a pixel
    box = np.zeros_like(blue)  # and nothing blue away from the body (a T-pose: thin arms)
    box[row.min() - 1: row.max() + 2, col.min() - 1: col.max() + 2] = True
    assert blue[box].mean() > 0.1 and blue[~box].sum() == 0


def test_frames_are_deterministic_and_the_target_is_highlighted():
    a = _clip().draw(1)
    b = _clip().draw(1)
    np.testing.assert_array_equal(a, b)
    amber = (a[..., 0].astype(int) - a[..., 2] > 120) & (a[..., 1] > 90)
    assert amber.sum() > 5  # the chair's seat, tinted


def test_follow_camera_pans_smoothly_and_grid_tiles():
    clip = _clip(size=(64, 48), t=150, walk=6.0, camera="auto")
    assert clip.mode == "follow" and clip.plan.zoom > 1.2
    cx = np.array([c.cx for c in clip.cameras])
    assert np.abs(np.diff(cx, 2)).max() < 1.0  # no jumps: smoothed
    assert clip.draw(0).shape == clip.draw(149).shape == (48, 64, 3)  # crops at the ends
    grid = _clip(size=(64, 48), k=2, samples="grid")
    assert grid.grid == (2, 1) and grid.draw(0).shape == (48, 64, 3)
    with pytest.raises(ValueError, match="overlay"):
        _clip(samples="side")
    with pytest.raises(ValueError, match="camera"):
        _clip(camera="orbit")


@pytest.mark.parametrize("camera", ["fixed", "follow"])
def test_the_cutaway_is_computed_on_the_picture_it_cuts(camera, monkeypatch):
    """The body's holes (where scene points would hide it) are found on the pixels of the
    picture the room is drawn into: the follow camera draws a zoomed picture, and holes found
    on the unzoomed one missed what stood in front of the body."""
    import jaxmotion.render.frames as F

    built, drawn = [], []

    class Holes(F.CutawayHoles):
        def __init__(self, cam, joints, **kw):
            built.append(cam)
            super().__init__(cam, joints, **kw)

    monkeypatch.setattr(F, "CutawayHoles", Holes)
    clip = _clip(size=(64, 48), t=150, walk=6.0, camera=camera)
    real = clip.scene.background
    monkeypatch.setattr(clip.scene, "background",
                        lambda cam, *a, **kw: drawn.append(cam) or real(cam, *a, **kw))
    clip.draw(75)
    assert len(built) == len(drawn) == 1
    assert (built[0].width, built[0].height, built[0].focal) == (
        drawn[0].width, drawn[0].height, drawn[0].focal)
    if camera == "follow":
        assert drawn[0].width > 64  # the zoomed picture the frames are cropped from


def test_video_and_still_files(tmp_path):
    import imageio.v3 as iio

    from jaxmotion.render import render_still, render_video

    clip = _clip(size=(64, 48), t=6)
    path = render_video(tmp_path / "m.mp4", clip, video_fps=15)
    frames = iio.imread(path, plugin="FFMPEG")
    assert frames.shape == (3, 48, 64, 3)  # 6 frames at 30 fps drawn at 15
    png = render_still(tmp_path / "m.png", clip, frame=-1)
    assert iio.imread(png).shape == (48, 64, 3)
    with pytest.raises(ValueError, match=".mp4 or .gif"):
        render_video(tmp_path / "m.avi", clip)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.mp4", "m.png"]


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_video_runs_work_beside_it_and_raises_its_error(tmp_path, suffix):
    """``meanwhile`` runs on another thread while the frames are drawn (generate writes its
    other files so); the video is the same, and an error there is raised with no video left."""
    import threading

    from jaxmotion.render import render_video

    clip = _clip(size=(64, 48), t=6)
    plain = render_video(tmp_path / f"a{suffix}", clip, video_fps=15).read_bytes()
    ran = []
    render_video(tmp_path / f"b{suffix}", clip, video_fps=15,
                 meanwhile=lambda: ran.append(threading.current_thread().name))
    assert ran and ran[0] != threading.current_thread().name
    assert (tmp_path / f"b{suffix}").read_bytes() == plain

    def fails():
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        render_video(tmp_path / f"c{suffix}", clip, video_fps=15, meanwhile=fails)
    assert not (tmp_path / f"c{suffix}").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"a{suffix}", f"b{suffix}"]


# --------------------------------------------------------------------------- command line


def _saved_sample(tmp_path):
    """A dataset-like folder: samples/test/x.npz with scenes/<scene_id>.npz beside it."""
    from jaxmotion.scene import save_scene

    p, joints = _standing(5)
    (tmp_path / "data" / "samples" / "test").mkdir(parents=True)
    (tmp_path / "data" / "scenes").mkdir()
    save_scene(_room(), tmp_path / "data" / "scenes" / "room7.npz")
    sample = tmp_path / "data" / "samples" / "test" / "room7_00.npz"
    np.savez(sample, text=np.array("stand by the chair"), action=np.array("walk"),
             scene_id=np.array("room7"), target_id=np.int64(1), joints=joints[0],
             fps=np.float64(30.0), mask=np.ones(5, bool), transl=p["transl"][0],
             global_orient=p["global_orient"][0], body_pose=p["body_pose"][0],
             betas=p["betas"][0])
    return sample


def test_render_command_draws_a_dataset_sample(tmp_path, capsys):
    import imageio.v3 as iio

    from jaxmotion.cli import main

    sample = _saved_sample(tmp_path)
    out = tmp_path / "still.png"
    assert main(["render", str(sample), "--out", str(out), "--size", "64x48", "--frame", "2"]) == 0
    assert iio.imread(out).shape == (48, 64, 3)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


@pytest.mark.parametrize("args, message", [
    (["nope.npz", "--out", "x.mp4"], "no such file"),
    (["SAMPLE", "--out", "x.mp4", "--size", "65x48"], "even"),
    (["SAMPLE", "--out", "x.mp4", "--size", "big"], "WIDTHxHEIGHT"),
    (["SAMPLE", "--out", "x.avi"], ".mp4, .gif or .png"),
    (["SAMPLE", "--out", "x.png", "--scene", "missing.ply"], "no such file"),
    (["SCENE", "--out", "x.png"], "not a motion.npz"),
])
def test_render_command_errors_are_one_line(tmp_path, capsys, args, message):
    from jaxmotion.cli import main

    sample = _saved_sample(tmp_path)
    scene = tmp_path / "data" / "scenes" / "room7.npz"
    args = [str(sample) if a == "SAMPLE" else str(scene) if a == "SCENE" else
            str(tmp_path / a) if a.startswith(("x.", "missing")) else a for a in args]
    assert main(["render", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1 and "Traceback" not in err
    assert not (tmp_path / "x.mp4").exists() and not (tmp_path / "x.png").exists()


def test_frames_drawn_by_threads_are_the_frames_drawn_one_by_one():
    from jaxmotion.render.frames import drawn_frames

    class Counting:
        def __init__(self):
            self.calls = []

        def draw(self, f):
            self.calls.append(f)
            return np.full((4, 4, 3), f % 251, np.uint8)

    frames = list(range(0, 40, 3))
    one = list(drawn_frames(Counting(), frames, workers=1))
    clip = Counting()
    two = list(drawn_frames(clip, frames, workers=2))
    assert [int(a[0, 0, 0]) for a in two] == [f % 251 for f in frames]
    assert all(np.array_equal(a, b) for a, b in zip(one, two, strict=True))
    assert clip.calls[0] == frames[0] and sorted(clip.calls) == frames
    assert list(drawn_frames(Counting(), [], workers=2)) == []


def test_vertex_normals_match_a_brute_force_sum():
    """The exporters' vertex normals: area-weighted face normals summed per vertex."""
    from jaxmotion.export._common import vertex_normals

    rng = np.random.default_rng(3)
    v = rng.normal(size=(40, 3)).astype(np.float32)
    f = np.stack([rng.choice(39, 3, replace=False) for _ in range(60)])  # vertex 39: no face
    want = np.zeros((40, 3))
    for a, b, c in f:
        n = np.cross(v[b] - v[a], v[c] - v[a])
        for i in (a, b, c):
            want[i] += n
    want /= np.maximum(np.linalg.norm(want, axis=1, keepdims=True), 1e-30)
    got = vertex_normals(v, f)
    np.testing.assert_allclose(got, want, atol=1e-5)
    assert np.all(got[39] == 0)
