"""Evaluation metrics vs numpy brute force, hand-made bodies and edge cases."""

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import linalg

from jaxmotion.eval import metrics as M

seeds = st.integers(0, 2**31 - 1)


def fibonacci_sphere(n, radius=1.0, centre=(0.0, 0.0, 0.0)):
    """Evenly spread vertices on a sphere and their outward normals."""
    i = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * i / n)
    theta = np.pi * (1 + 5**0.5) * i
    nrm = np.stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)], 1)
    return (radius * nrm + np.asarray(centre)).astype(np.float32), nrm.astype(np.float32)


def brute_body_sdf(p, v, n):
    d = np.linalg.norm(p[:, None].astype(np.float64) - v[None], axis=-1)
    i = d.argmin(1)
    side = np.sum((v[i] - p) * n[i], axis=-1)
    srt = np.sort(d, axis=1)
    gap = srt[:, 1] - srt[:, 0] if v.shape[0] > 1 else np.full(len(p), np.inf)
    return np.where(side > 0, d.min(1), -d.min(1)), gap


# ----------------------------------------------------------------------------- body SDF
@settings(max_examples=12)
@given(
    seeds,
    st.sampled_from([13, 300]),
    st.sampled_from([1, 200]),
    st.sampled_from([{}, {"query_chunk": 7, "block": 16}, {"exact": True}]),
)
def test_signed_distance_to_body_matches_brute_force(seed, n, v, kw):
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(n, 3)).astype(np.float32)
    verts = rng.normal(size=(v, 3)).astype(np.float32)
    nrm = rng.normal(size=(v, 3)).astype(np.float32)
    s = np.asarray(M.signed_distance_to_body(p, verts, nrm, **kw))
    ref, gap = brute_body_sdf(p, verts, nrm)
    np.testing.assert_allclose(np.abs(s), np.abs(ref), atol=1e-5)
    clear = gap > 1e-4  # the sign follows the nearest vertex: skip exact ties
    np.testing.assert_array_equal(np.sign(s[clear]), np.sign(ref[clear]))


def test_body_sdf_of_a_sphere_is_positive_inside():
    verts, nrm = fibonacci_sphere(4000)
    rng = np.random.default_rng(1)
    dirs = rng.normal(size=(400, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    radius = rng.uniform(0.0, 2.0, 400)
    p = (dirs * radius[:, None]).astype(np.float32)
    s = np.asarray(M.signed_distance_to_body(p, verts, nrm))
    far = np.abs(radius - 1) > 0.06  # vertices are ~5.6 cm apart
    assert np.all(s[far & (radius < 1)] > 0) and np.all(s[far & (radius > 1)] < 0)
    np.testing.assert_allclose(s[radius > 1], 1 - radius[radius > 1], atol=0.045)
    # Scaling the normals does not change anything.
    np.testing.assert_array_equal(s, M.signed_distance_to_body(p, verts, 3 * nrm))


def test_fast_body_sdf_matches_exact_near_the_surface():
    """Scene points on and just off the vertices (near-ties) of an off-centre ellipsoid."""
    verts, nrm = fibonacci_sphere(2000, radius=0.5, centre=(3.0, -2.0, 1.0))
    verts = verts * np.float32([0.4, 0.6, 1.8])
    rng = np.random.default_rng(9)
    p = np.concatenate(
        [
            verts + rng.normal(0, 1e-3, verts.shape),
            verts.mean(0) + rng.normal(0, 1.5, (500, 3)),
        ]
    ).astype(np.float32)
    fast = np.asarray(M.signed_distance_to_body(p, verts, nrm))
    exact = np.asarray(M.signed_distance_to_body(p, verts, nrm, exact=True))
    np.testing.assert_allclose(fast, exact, atol=1e-5)


def test_body_sdf_frames_jit_and_vmap_agree():
    rng = np.random.default_rng(2)
    p = rng.normal(size=(50, 3)).astype(np.float32)
    verts = rng.normal(size=(4, 30, 3)).astype(np.float32)
    nrm = rng.normal(size=(4, 30, 3)).astype(np.float32)
    loop = np.stack([M.signed_distance_to_body(p, verts[t], nrm[t]) for t in range(4)])
    frames = M.signed_distance_to_body_frames(p, verts, nrm)
    vm = jax.vmap(M.signed_distance_to_body, in_axes=(None, 0, 0))(p, verts, nrm)
    jt = jax.jit(M.signed_distance_to_body_frames)(p, verts, nrm)
    for x in (frames, vm, jt):
        np.testing.assert_allclose(x, loop, atol=1e-6)


def test_body_sdf_rejects_bad_shapes():
    with pytest.raises(ValueError, match="vertex_normals"):
        M.signed_distance_to_body(np.zeros((3, 3)), np.zeros((4, 3)), np.zeros((5, 3)))
    with pytest.raises(ValueError, match="no vertices"):
        M.signed_distance_to_body(np.zeros((3, 3)), np.zeros((0, 3)), np.zeros((0, 3)))


# ----------------------------------------------------------------------------- rates
def brute_rates(sdf, mask, pmask, thr):
    t_ok = np.ones(len(sdf), bool) if mask is None else mask
    p_ok = np.ones(sdf.shape[1], bool) if pmask is None else pmask
    nc = [np.mean(sdf[t][p_ok] <= 0) for t in range(len(sdf)) if t_ok[t]]
    ct = [float(np.any(sdf[t][p_ok] > thr)) for t in range(len(sdf)) if t_ok[t]]
    return np.mean(nc), np.mean(ct)


@settings(max_examples=12)
@given(seeds, st.sampled_from([(1, 1), (12, 40)]), st.booleans(), st.booleans())
def test_non_collision_and_contact_match_brute_force(seed, shape, use_mask, use_pmask):
    rng = np.random.default_rng(seed)
    sdf = rng.normal(-0.1, 0.08, shape).astype(np.float32)
    mask = rng.random(shape[0]) < 0.7 if use_mask else None
    pmask = rng.random(shape[1]) < 0.7 if use_pmask else None
    if mask is not None:
        mask[rng.integers(shape[0])] = True
    if pmask is not None:
        pmask[rng.integers(shape[1])] = True
    for thr in (-0.05, 0.0):
        nc, ct = brute_rates(sdf, mask, pmask, thr)
        np.testing.assert_allclose(M.non_collision(sdf, mask, point_mask=pmask), nc, rtol=1e-6)
        np.testing.assert_allclose(M.contact(sdf, thr, mask, point_mask=pmask), ct, rtol=1e-6)


def test_rates_hand_made_and_jit():
    sdf = np.array([[-1.0, -0.01, -0.2], [0.1, -1.0, -1.0], [-1.0, -1.0, -1.0]], np.float32)
    np.testing.assert_allclose(M.non_collision(sdf), (1 + 2 / 3 + 1) / 3, rtol=1e-6)
    np.testing.assert_allclose(M.contact(sdf), 2 / 3, rtol=1e-6)  # −0.01 > −0.05
    np.testing.assert_allclose(M.contact(sdf, 0.0), 1 / 3, rtol=1e-6)  # HUMANISE threshold
    mask = np.array([True, True, False])
    np.testing.assert_allclose(jax.jit(M.non_collision)(sdf, mask), (1 + 2 / 3) / 2, rtol=1e-6)
    np.testing.assert_allclose(jax.jit(M.contact)(sdf, -0.05, mask), 1.0)
    batch = np.stack([sdf, -np.abs(sdf)])  # vmap over samples
    np.testing.assert_allclose(jax.vmap(M.non_collision)(batch), [M.non_collision(sdf), 1.0])


def test_all_frames_masked():
    sdf = np.zeros((3, 4), np.float32)
    none = np.zeros(3, bool)
    for fn in (M.non_collision, M.contact):
        with pytest.raises(ValueError, match="no frame"):
            fn(sdf, mask=none)
        assert np.isnan(jax.jit(partial(fn, sdf))(mask=none))
    with pytest.raises(ValueError, match="no scene point"):
        M.non_collision(sdf, point_mask=np.zeros(4, bool))
    with pytest.raises(ValueError, match="at least one frame"):
        M.non_collision(np.zeros((0, 4)))
    with pytest.raises(ValueError, match="mask must have shape"):
        M.contact(sdf, mask=np.ones(2, bool))


# ----------------------------------------------------------------------------- goal distance
def test_anchor_index():
    mask = np.array([False, True, True, True, False])
    assert int(M.anchor_index(mask, "sit")) == 3
    assert int(M.anchor_index(mask, "walk to the table")) == 3
    for a in ("stand_up", "stand up", "Stand up from the sofa", "  STAND_UP"):
        assert int(M.anchor_index(mask, a)) == 1
    assert int(M.anchor_index(np.ones(4, bool), "lie")) == 3
    assert int(jax.jit(partial(M.anchor_index, action="stand up"))(mask)) == 1
    with pytest.raises(ValueError, match="no frame"):
        M.anchor_index(np.zeros(4, bool), "sit")


@settings(max_examples=10)
@given(seeds, st.sampled_from([1, 80]), st.booleans())
def test_goal_distance_matches_brute_force(seed, m, use_mask):
    rng = np.random.default_rng(seed)
    verts, nrm = fibonacci_sphere(300, radius=0.5)
    target = rng.uniform(-1.2, 1.2, (m, 3)).astype(np.float32)
    tmask = None
    if use_mask:
        tmask = rng.random(m) < 0.5
        tmask[0] = True
    s, _ = brute_body_sdf(target, verts, nrm)
    ok = np.ones(m, bool) if tmask is None else tmask
    ref = np.maximum(-s[ok], 0).min()
    np.testing.assert_allclose(
        M.goal_distance(target, verts, nrm, target_mask=tmask), ref, atol=1e-5
    )


def test_goal_distance_hand_made():
    verts, nrm = fibonacci_sphere(3000)  # unit sphere body
    cube = np.random.default_rng(3).uniform(-0.1, 0.1, (200, 3)).astype(np.float32)
    near = cube + np.float32([1.4, 0, 0])  # closest point at x = 1.3: gap 0.3
    np.testing.assert_allclose(M.goal_distance(near, verts, nrm), 0.3, atol=0.01)
    touching = cube + np.float32([1.05, 0, 0])  # overlaps the body
    assert float(M.goal_distance(touching, verts, nrm)) == 0.0
    # Anchor: a body that moves away; "stand up" reads the first frame.
    frames = np.stack([verts, verts + np.float32([-1, 0, 0])])
    normals = np.stack([nrm, nrm])
    last = M.anchor_goal_distance(near, frames, normals, None, "sit")
    first = M.anchor_goal_distance(near, frames, normals, None, "stand up from the chair")
    np.testing.assert_allclose([first, last], [0.3, 1.3], atol=0.01)


def test_goal_distance_empty_target():
    verts, nrm = fibonacci_sphere(50)
    with pytest.raises(ValueError, match="target_points is empty"):
        M.goal_distance(np.zeros((0, 3)), verts, nrm)
    with pytest.raises(ValueError, match="target object is empty"):
        M.goal_distance(np.zeros((3, 3)), verts, nrm, target_mask=np.zeros(3, bool))
    with pytest.raises(ValueError, match="target_points is empty"):
        M.joints_goal_distance(np.zeros((0, 3)), np.zeros((22, 3)))


# ----------------------------------------------------------------------------- APD
def brute_apd(x, mask=None):
    k, t = x.shape[:2]
    x = x.reshape(k, t, -1).astype(np.float64)
    per_frame = []
    for f in range(t):
        if mask is not None and not mask[f]:
            continue
        pairs = [np.linalg.norm(x[i, f] - x[j, f]) for i in range(k) for j in range(i + 1, k)]
        per_frame.append(np.mean(pairs) if pairs else 0.0)
    return np.mean(per_frame)


@settings(max_examples=15)
@given(seeds, st.sampled_from([1, 2, 5]), st.sampled_from([(1, 3), (4, 22, 3)]), st.booleans())
def test_apd_matches_brute_force(seed, k, shape, use_mask):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(k, *shape)).astype(np.float32)
    mask = None
    if use_mask:
        mask = rng.random(shape[0]) < 0.6
        mask[-1] = True
    np.testing.assert_allclose(M.apd(x, mask), brute_apd(x, mask), rtol=1e-5, atol=1e-6)


def test_apd_edge_cases():
    x = np.random.default_rng(4).normal(size=(1, 5, 6))
    assert float(M.apd(x)) == 0.0
    two = np.zeros((2, 3, 2), np.float32)
    two[1, :, 0] = [1.0, 2.0, 3.0]
    np.testing.assert_allclose(M.apd(two), 2.0)
    np.testing.assert_allclose(jax.jit(M.apd)(two, np.array([True, False, False])), 1.0)
    with pytest.raises(ValueError, match="no frame"):
        M.apd(two, np.zeros(3, bool))
    with pytest.raises(ValueError, match="at least one sample"):
        M.apd(np.zeros((0, 3, 2)))
    cases = np.stack([two, 2 * two])  # vmap over cases
    np.testing.assert_allclose(jax.vmap(M.apd)(cases), [2.0, 4.0], rtol=1e-6)


# ----------------------------------------------------------------------------- joint spheres
@given(seeds, st.sampled_from([1, 30]), st.sampled_from([1, 22]))
def test_joint_sphere_sdf_matches_brute_force(seed, n, j):
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(n, 3)).astype(np.float32)
    c = rng.normal(size=(j, 3)).astype(np.float32)
    r = rng.uniform(0.05, 0.5, j).astype(np.float32)
    d = np.linalg.norm(p[:, None].astype(np.float64) - c[None], axis=-1)
    np.testing.assert_allclose(M.joint_sphere_sdf(p, c, r), np.max(r - d, axis=1), atol=1e-5)


def test_joint_radii_table():
    assert len(M.JOINT_RADII) == 22 and all(0.01 < r < 0.15 for r in M.JOINT_RADII)
    # A flat foot (toe joint 2.5 cm, ankle 7 cm up) does not pierce the floor.
    assert M.JOINT_RADII[10] < 0.025 and M.JOINT_RADII[7] < 0.07


def test_joints_variant_agrees_with_vertex_version_on_a_sphere():
    """One joint of radius 1 vs the same sphere as a vertex mesh."""
    verts, nrm = fibonacci_sphere(6000)
    rng = np.random.default_rng(5)
    scene = rng.uniform(-1.6, 1.6, (500, 3)).astype(np.float32)
    s_vert = np.asarray(M.signed_distance_to_body(scene, verts, nrm))
    s_joint = np.asarray(M.joint_sphere_sdf(scene, np.zeros((1, 3)), np.ones(1)))
    np.testing.assert_allclose(s_joint, s_vert, atol=0.03)  # vertex spacing ~2.9 cm
    assert np.mean(np.sign(s_joint) == np.sign(s_vert)) > 0.97

    # A motion of 3 frames moving along x; the target sits at x = 3.
    shift = np.float32([[0, 0, 0], [1, 0, 0], [1.5, 0, 0]])
    joints = shift[:, None, :]  # [T, 1, 3]
    target = (rng.uniform(-0.1, 0.1, (100, 3)) + [3.0, 0, 0]).astype(np.float32)
    fast = M.joints_physical_metrics(scene, joints, target, None, "walk", radii=np.ones(1))
    sdf = M.signed_distance_to_body_frames(scene, verts[None] + shift[:, None], np.stack([nrm] * 3))
    np.testing.assert_allclose(fast["non_collision"], M.non_collision(sdf), atol=0.02)
    np.testing.assert_allclose(fast["contact"], M.contact(sdf))
    slow_goal = M.anchor_goal_distance(
        target, verts[None] + shift[:, None], np.stack([nrm] * 3), None, "walk"
    )
    np.testing.assert_allclose(fast["goal_distance"], slow_goal, atol=0.03)
    np.testing.assert_allclose(fast["goal_distance"], 3.0 - 0.1 - 1.5 - 1.0, atol=0.03)


def test_joints_physical_metrics_jit_vmap_and_default_radii():
    rng = np.random.default_rng(6)
    scene = rng.uniform(-2, 2, (200, 3)).astype(np.float32)
    joints = rng.normal(0, 0.4, (3, 5, 22, 3)).astype(np.float32)  # [B, T, J, 3]
    target = rng.uniform(-2, 2, (20, 3)).astype(np.float32)
    fn = jax.jit(jax.vmap(partial(M.joints_physical_metrics, scene, target_points=target)))
    out = fn(joints)
    ref = M.joints_physical_metrics(scene, joints[1], target)
    for key in ("non_collision", "contact", "goal_distance"):
        np.testing.assert_allclose(out[key][1], ref[key], rtol=1e-6, atol=1e-7)


# ----------------------------------------------------------------------------- foot skating
def brute_skating(j, mask, fps, feet, offs, h, v):
    t = len(j)
    flags, speeds = [], []
    for f in range(t - 1):
        if mask is not None and not (mask[f] and mask[f + 1]):
            continue
        skate = False
        for k, o in zip(feet, offs):
            contact = j[f, k, 2] - o < h and j[f + 1, k, 2] - o < h
            sp = np.linalg.norm(j[f + 1, k, :2] - j[f, k, :2]) * fps
            if contact:
                speeds.append(sp)
                skate |= sp > v
        flags.append(skate)
    return np.mean(flags), (np.mean(speeds) if speeds else 0.0)


@settings(max_examples=15)
@given(seeds, st.sampled_from([2, 40]), st.booleans(), st.sampled_from([20.0, 30.0]))
def test_foot_skating_matches_brute_force(seed, t, use_mask, fps):
    rng = np.random.default_rng(seed)
    j = rng.normal(0, 0.3, (t, 22, 3)).astype(np.float32)
    j[..., 2] = rng.uniform(0.0, 0.15, (t, 22))
    j[:, :, :2] = np.cumsum(rng.normal(0, 0.02, (t, 22, 2)), axis=0)
    mask = None
    if use_mask:
        mask = rng.random(t) < 0.7
        mask[:2] = True
    out = M.foot_skating(j, mask, fps=fps)
    ratio, vel = brute_skating(j, mask, fps, M.FOOT_JOINTS, M.FOOT_FLOOR_OFFSETS, 0.05, 0.5)
    np.testing.assert_allclose(out["skate_ratio"], ratio, rtol=1e-6)
    np.testing.assert_allclose(out["skate_velocity"], vel, rtol=1e-4, atol=1e-6)


def test_foot_skating_sliding_vs_lifted():
    t = 30
    j = np.zeros((t, 22, 3), np.float32)
    j[:, 1:, 2] = 1.0  # every joint high up...
    j[:, 10, 2] = 0.025  # ...except the left toe, flat on the floor
    j[:, 10, 0] = np.arange(t) * 0.03  # sliding at 0.9 m/s (30 fps)
    out = M.foot_skating(j, fps=30)
    np.testing.assert_allclose([out["skate_ratio"], out["skate_velocity"]], [1.0, 0.9], rtol=1e-5)
    lifted = j.copy()
    lifted[:, 10, 2] = 0.2  # the same motion in the air: a swing, not a skid
    out = M.foot_skating(lifted, fps=30)
    assert float(out["skate_ratio"]) == 0.0 and float(out["skate_velocity"]) == 0.0
    slow = j.copy()
    slow[:, 10, 0] = np.arange(t) * 0.005  # 0.15 m/s: under the 0.5 m/s threshold
    assert float(M.foot_skating(slow, fps=30)["skate_ratio"]) == 0.0
    mask = np.ones(t, bool)
    mask[10:] = False  # masked frames ignored
    half = j.copy()
    half[10:, 10, 2] = 0.025
    half[10:, 10, 0] = 0.27
    np.testing.assert_allclose(jax.jit(M.foot_skating)(half, mask)["skate_ratio"], 1.0)
    with pytest.raises(ValueError, match="consecutive"):
        M.foot_skating(j, np.arange(t) % 2 == 0)
    with pytest.raises(ValueError, match="at least 2 frames"):
        M.foot_skating(j[:1])


# ----------------------------------------------------------------------------- grounding
def brute_grounding(d, tmask):
    dt = d[tmask].astype(np.float64)
    out = {"min_dist": dt.min(1).mean(), "pelvis_dist": dt[:, 0].mean(), "all_dist": dt.mean()}
    for delta in (0.1, 0.3, 0.5):
        out[f"success@{delta:g}"] = float(dt.min() < delta)
    return out


@given(seeds, st.sampled_from([1, 20, 300]))
def test_affordance_grounding_matches_brute_force(seed, n):
    rng = np.random.default_rng(seed)
    d = rng.uniform(0.0, 1.5, (n, 6)).astype(np.float32)
    tmask = rng.random(n) < 0.4
    tmask[rng.integers(n)] = True
    got = M.affordance_grounding(d, tmask)
    ref = brute_grounding(d, tmask)
    assert set(got) == set(ref)
    for key, value in ref.items():
        np.testing.assert_allclose(got[key], value, rtol=1e-5, err_msg=key)
    a = np.exp(-(d**2) / (2 * 0.8**2))
    from_map = M.affordance_grounding_from_map(a, tmask)
    for key, value in ref.items():
        np.testing.assert_allclose(from_map[key], value, atol=2e-3, err_msg=key)


def test_affordance_grounding_hand_made_jit_vmap_and_empty():
    d = np.full((4, 6), 2.0, np.float32)
    d[1] = [0.4, 0.2, 0.9, 1.0, 1.0, 1.0]
    d[2] = [0.6, 0.8, 0.7, 0.25, 1.0, 1.0]
    tmask = np.array([False, True, True, False])
    got = jax.jit(M.affordance_grounding)(d, tmask)
    np.testing.assert_allclose(got["min_dist"], (0.2 + 0.25) / 2, rtol=1e-6)
    np.testing.assert_allclose(got["pelvis_dist"], 0.5, rtol=1e-6)
    assert [float(got[f"success@{x}"]) for x in (0.1, 0.3, 0.5)] == [0.0, 1.0, 1.0]
    batch = jax.vmap(M.affordance_grounding)(np.stack([d, d + 1]), np.stack([tmask, tmask]))
    np.testing.assert_allclose(batch["all_dist"], [got["all_dist"], got["all_dist"] + 1], rtol=1e-6)
    with pytest.raises(ValueError, match="target object is empty"):
        M.affordance_grounding(d, np.zeros(4, bool))
    assert np.isnan(jax.jit(M.affordance_grounding)(d, np.zeros(4, bool))["min_dist"])


def test_grounding_accuracy():
    assert float(M.grounding_accuracy([1, 2, 3, 4], [1, 0, 3, 0])) == 0.5
    mask = np.array([True, False, True, False])
    assert (
        float(jax.jit(M.grounding_accuracy)(np.array([1, 2, 3, 4]), np.array([1, 0, 3, 0]), mask))
        == 1.0
    )
    with pytest.raises(ValueError):
        M.grounding_accuracy([], [])


# ----------------------------------------------------------------------------- text-motion
def brute_fid(a, b):
    mu_a, mu_b = a.mean(0), b.mean(0)
    ca, cb = np.cov(a, rowvar=False), np.cov(b, rowvar=False)
    w, u = np.linalg.eigh(ca)
    root_a = (u * np.sqrt(np.maximum(w, 0))) @ u.T
    inner = np.linalg.eigvalsh(root_a @ cb @ root_a)  # tr sqrt(Σa Σb) = tr sqrt(√Σa Σb √Σa)
    return (
        np.sum((mu_a - mu_b) ** 2)
        + np.trace(ca)
        + np.trace(cb)
        - 2 * np.sum(np.sqrt(np.maximum(inner, 0)))
    )


@settings(max_examples=10)
@given(seeds, st.sampled_from([(50, 3), (200, 16)]))
def test_fid_matches_brute_force(seed, shape):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=shape)
    b = rng.normal(size=shape) @ rng.normal(size=(shape[1], shape[1])) * 0.5 + 0.3
    np.testing.assert_allclose(M.fid(a, b), brute_fid(a, b), rtol=1e-6, atol=1e-8)
    assert abs(M.fid(a, a)) < 1e-6
    np.testing.assert_allclose(M.fid(a, a + 2.0), 4.0 * shape[1], rtol=1e-6)
    with pytest.raises(ValueError):
        M.fid(a[:1], b)


def brute_r_precision(t, m, top_k, pool):
    hits, total = np.zeros(top_k), 0
    for s in range(0, len(t) - pool + 1, pool):
        for i in range(pool):
            d = [np.linalg.norm(t[s + i] - m[s + j]) for j in range(pool)]
            rank = sorted(range(pool), key=lambda j: (d[j], j)).index(i)
            hits += [rank < k for k in range(1, top_k + 1)]
            total += 1
    return hits / total


@settings(max_examples=10)
@given(seeds, st.sampled_from([(32, 4), (70, 8)]), st.sampled_from([(3, 32), (2, 8)]))
def test_r_precision_matches_brute_force(seed, shape, kp):
    rng = np.random.default_rng(seed)
    m = rng.normal(size=shape)
    t = m + rng.normal(size=shape) * 1.0
    np.testing.assert_allclose(M.r_precision(t, m, *kp), brute_r_precision(t, m, *kp))


def test_r_precision_and_friends_hand_made():
    rng = np.random.default_rng(7)
    m = rng.normal(size=(64, 8))
    np.testing.assert_allclose(M.r_precision(m, m), [1.0, 1.0, 1.0])
    shuffled = M.r_precision(m, m, rng=np.random.default_rng(0))
    np.testing.assert_allclose(shuffled, [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="full pool"):
        M.r_precision(m[:31], m[:31])
    np.testing.assert_allclose(M.multimodal_distance(m, m + [3, 4, 0, 0, 0, 0, 0, 0]), 5.0)


def test_diversity_and_multimodality_match_brute_force():
    rng = np.random.default_rng(8)
    f = rng.normal(size=(400, 5))
    g = np.random.default_rng(11)
    a, b = g.choice(400, 300, replace=False), g.choice(400, 300, replace=False)
    ref = np.mean([np.linalg.norm(f[i] - f[j]) for i, j in zip(a, b)])
    np.testing.assert_allclose(M.diversity(f, 300, np.random.default_rng(11)), ref)
    assert M.diversity(f, 300, 5) == M.diversity(f, 300, np.random.default_rng(5))
    with pytest.raises(ValueError, match="num_pairs"):
        M.diversity(f[:100])

    c = rng.normal(size=(6, 30, 5))
    g = np.random.default_rng(12)
    a, b = g.choice(30, 10, replace=False), g.choice(30, 10, replace=False)
    ref = np.mean([[np.linalg.norm(c[k, i] - c[k, j]) for i, j in zip(a, b)] for k in range(6)])
    np.testing.assert_allclose(M.multimodality(c, 10, np.random.default_rng(12)), ref)
    same = np.repeat(c[:, :1], 30, axis=1)  # every sample identical
    assert M.multimodality(same, 10, 0) == 0.0
    with pytest.raises(ValueError, match="per case"):
        M.multimodality(c[:, :5])


def test_frechet_distance_uses_sqrtm_like_the_reference():
    s1 = np.array([[2.0, 0.3], [0.3, 1.0]])
    s2 = np.array([[1.0, -0.2], [-0.2, 0.5]])
    ref = np.trace(s1 + s2 - 2 * linalg.sqrtm(s1 @ s2).real) + 1.0
    np.testing.assert_allclose(M.frechet_distance([0, 0], s1, [1, 0], s2), ref)



def test_fid_of_fewer_samples_than_dimensions_is_finite_and_warns_nothing():
    """Two samples of 8-dimensional features: both covariances are singular (scipy's sqrtm
    warns the root may be inaccurate); the offset retry gives the distance of the eps-regular
    covariances, checked against the symmetric square-root form."""
    import warnings

    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(2, 8)), rng.normal(size=(2, 8)) + 0.5
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        d = M.fid(a, b)
    s1, s2 = (np.cov(x, rowvar=False) + 1e-6 * np.eye(8) for x in (a, b))
    w, v = np.linalg.eigh(s1)
    r1 = (v * np.sqrt(np.clip(w, 0, None))) @ v.T
    tr = np.sqrt(np.clip(np.linalg.eigvalsh(r1 @ s2 @ r1), 0, None)).sum()
    diff = a.mean(0) - b.mean(0)
    np.testing.assert_allclose(d, diff @ diff + np.trace(s1) + np.trace(s2) - 2 * tr, rtol=1e-4)

def test_package_exports():
    import jaxmotion.eval as E

    for name in ("signed_distance_to_body", "non_collision", "contact", "apd", "fid"):
        assert getattr(E, name) is getattr(M, name)
    assert jnp.asarray(M.JOINT_RADII).shape == (22,)
