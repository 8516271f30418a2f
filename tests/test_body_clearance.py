"""Body clearance (jaxmotion.diffusion.body_clearance): the distance field and its
interpolation against brute-force NumPy, the term's gradients, and the guidance moving a limb
out of an obstacle while the pelvis stays."""

import jax
import jax.numpy as jnp
import numpy as np
from jax.test_util import check_grads

from jaxmotion.diffusion import body_clearance as B
from jaxmotion.diffusion import foot_guidance as F
from jaxmotion.geometry.rotations import matrix_to_rotation_6d
from jaxmotion.geometry.skeleton import upright_orientation
from jaxmotion.motion.representation import MOTION_DIM, TRAJECTORY_DIM, motion_to_joints

L_KNEE, R_KNEE = 4, 5


def _nodes():
    g = np.arange(B.FIELD_SHAPE[0]) * B.CELL - B.HALF
    z = np.arange(B.FIELD_SHAPE[2]) * B.CELL
    return np.stack(np.meshgrid(g, g, z, indexing="ij"), -1)


def _brute_field(points, at=None):
    """Brute-force distances at the nodes ``at`` (flat indices; default all)."""
    nodes = _nodes().reshape(-1, 3)
    at = np.arange(len(nodes)) if at is None else at
    d = np.full(len(at), B.CLIP)
    for chunk in range(0, len(at), 20000):
        diff = nodes[at[chunk:chunk + 20000], None] - points[None]
        d[chunk:chunk + 20000] = np.minimum(np.sqrt((diff ** 2).sum(-1)).min(1), B.CLIP)
    return d


def test_distance_field_matches_brute_force():
    rng = np.random.default_rng(0)
    box = rng.uniform([0.3, -0.6, 0.1], [0.8, -0.2, 0.7], (300, 3))  # a chair-sized cluster
    scattered = rng.uniform([-2.3, -2.3, 0.0], [2.3, 2.3, 2.1], (60, 3))  # a few off the grid
    far = np.array([[9.0, 9.0, 1.0]])  # beyond the grid: no effect
    pts = np.concatenate([box, scattered, far])
    field = B.distance_field(pts)
    assert field.shape == B.FIELD_SHAPE and field.dtype == np.float32
    # every node near a point, and a random fifth of the rest (all CLIP)
    flat = field.reshape(-1)
    near = np.flatnonzero(flat < B.CLIP)
    far = np.random.default_rng(5).choice(np.flatnonzero(flat >= B.CLIP), flat.size // 5,
                                          replace=False)
    brute = _brute_field(pts[:-1], np.concatenate([near, far]))
    assert len(near) > 1000 and (brute[:len(near)] < B.CLIP).all()
    np.testing.assert_allclose(flat[np.concatenate([near, far])], brute, atol=1e-6)
    # and the nodes brute force puts near a point are the field's near ones
    assert (brute[len(near):] >= B.CLIP - 1e-6).all()
    np.testing.assert_array_equal(B.distance_field(np.zeros((0, 3))), B.empty_field())


def test_room_field_is_in_the_crop_frame_without_floor_and_target():
    rng = np.random.default_rng(1)
    floor = np.c_[rng.uniform(-2, 2, (400, 2)), np.full(400, 0.03)]
    post = np.c_[np.full((50, 2), [1.0, 0.5]), np.linspace(0.0, 1.0, 50)]
    target = np.c_[np.full((30, 2), [-1.0, 0.0]), np.linspace(0.2, 0.5, 30)]
    xyz = np.concatenate([floor, post, target]) + [5.0, 3.0, 0.0]  # the room's own frame
    obstacle = np.r_[np.ones(450, bool), np.zeros(30, bool)]
    a = 0.7
    rot = np.array([[np.cos(a), np.sin(a), 0], [-np.sin(a), np.cos(a), 0], [0, 0, 1]])
    shift = np.array([5.0, 3.0, 0.0])
    field = B.room_field(xyz, obstacle, shift, rot)
    crop = (xyz - shift) @ rot.T
    kept = crop[obstacle & (crop[:, 2] >= B.LOW)]  # the post above 0.1 m only
    np.testing.assert_allclose(field.reshape(-1), _brute_field(kept), atol=1e-6)


def test_field_distance_interpolates_between_nodes():
    rng = np.random.default_rng(2)
    field = rng.uniform(0, B.CLIP, B.FIELD_SHAPE).astype(np.float32)
    nodes = _nodes()
    idx = rng.integers(0, np.array(B.FIELD_SHAPE) - 1, (50, 3))
    w = rng.uniform(0, 1, (50, 3))
    p = nodes[idx[:, 0], idx[:, 1], idx[:, 2]] + w * B.CELL
    expect = np.zeros(50)
    for c in range(8):
        bits = np.array([(c >> a) & 1 for a in range(3)])
        i = idx + bits
        expect += np.prod(np.where(bits, w, 1 - w), -1) * field[i[:, 0], i[:, 1], i[:, 2]]
    got = np.asarray(B.field_distance(jnp.asarray(field), jnp.asarray(p, jnp.float32)))
    np.testing.assert_allclose(got, expect, atol=1e-5)
    at_nodes = nodes[idx[:, 0], idx[:, 1], idx[:, 2]]
    np.testing.assert_allclose(np.asarray(B.field_distance(jnp.asarray(field), jnp.asarray(
        at_nodes, jnp.float32))), field[idx[:, 0], idx[:, 1], idx[:, 2]], atol=1e-5)
    outside = jnp.asarray([[3.0, 0.0, 1.0], [0.0, 0.0, -0.5], [0.0, 0.0, 2.5]])
    np.testing.assert_allclose(np.asarray(B.field_distance(jnp.asarray(field), outside)),
                               B.CLIP)
    # inside cells, away from their faces (the interpolation's kinks)
    pts = jnp.asarray(at_nodes[:5] + rng.uniform(0.3, 0.7, (5, 3)) * B.CELL, jnp.float32)
    check_grads(lambda q: B.field_distance(jnp.asarray(field, jnp.float32), q), (pts,),
                order=1, modes=["rev"], eps=1e-3, atol=2e-2, rtol=2e-2)


def test_joints_clearance_matches_a_loop():
    rng = np.random.default_rng(3)
    post = np.c_[np.full((40, 2), [0.3, 0.1]), np.linspace(0.1, 1.2, 40)]
    field = B.distance_field(post)
    joints = rng.uniform([0.1, -0.1, 0.1], [0.5, 0.3, 1.1], (6, 22, 3)).astype(np.float32)
    mask = np.array([1, 1, 0, 1, 1, 0], bool)
    got = float(B.joints_clearance(jnp.asarray(joints), jnp.asarray(field), jnp.asarray(mask)))
    d = np.asarray(B.field_distance(jnp.asarray(field), jnp.asarray(joints)))
    expect = 0.0
    for t in range(6):
        for j in range(22):
            if mask[t]:
                expect += max(B.MARGIN - d[t, j], 0.0) ** 2 / B.SCALE ** 2
    assert expect > 0
    np.testing.assert_allclose(got, expect / B.FRAMES, rtol=1e-5)
    clear = np.array(joints)
    clear[..., 0] += 3.0  # all joints off the grid: nothing to pay
    assert float(B.joints_clearance(jnp.asarray(clear), jnp.asarray(field),
                                    jnp.asarray(mask))) == 0.0


def _standing(t=30):
    f = np.zeros((t, MOTION_DIM), np.float32)
    f[:, 2] = 0.93
    f[:, 3:9] = np.asarray(matrix_to_rotation_6d(upright_orientation(0.0)))
    f[:, TRAJECTORY_DIM:] = np.tile(np.asarray(matrix_to_rotation_6d(jnp.eye(3))), 21)
    return f


def test_guidance_moves_a_knee_out_of_an_obstacle_and_keeps_the_pelvis():
    f = _standing()
    joints = np.asarray(motion_to_joints(jnp.asarray(f)))
    knee = joints[0, R_KNEE]
    # a wall of points 3 cm beside the right knee, on its outer side (y: the body's left)
    side = np.sign(knee[1] - joints[0, L_KNEE][1])
    xs, zs = np.meshgrid(np.linspace(-0.3, 0.3, 31), np.linspace(0.2, 0.8, 31))
    wall = np.c_[xs.ravel() + knee[0], np.full(xs.size, knee[1] + side * 0.03), zs.ravel()]
    field = jnp.asarray(B.distance_field(wall))
    mask = jnp.ones(len(f), bool)
    mean, std = jnp.zeros(MOTION_DIM), jnp.full(MOTION_DIM, 0.05)
    loss = lambda x: B.clearance_loss(x, None, field, mask)
    refine = jax.jit(F.make_refiner(loss, mean, std, iterations=30))
    x = jnp.asarray(f / 0.05)[None]
    out = np.asarray(refine(x, jnp.zeros(1, int)))[0] * 0.05
    before = np.asarray(B.field_distance(field, jnp.asarray(joints[:, R_KNEE])))
    moved = np.asarray(motion_to_joints(jnp.asarray(out)))
    after = np.asarray(B.field_distance(field, jnp.asarray(moved[:, R_KNEE])))
    assert before.max() < 0.035 and after.min() > before.max() + 0.02
    assert float(loss(jnp.asarray(out))) < 0.2 * float(loss(jnp.asarray(f)))
    np.testing.assert_array_equal(out[:, :TRAJECTORY_DIM], f[:, :TRAJECTORY_DIM])
    np.testing.assert_allclose(moved[:, 0], joints[:, 0], atol=1e-6)  # the pelvis stays
    # the knee moved away from the wall, the other leg barely
    assert side * (moved[:, R_KNEE, 1] - knee[1]).mean() < -0.01
    assert np.abs(moved[:, L_KNEE] - joints[:, L_KNEE]).max() < 0.01
