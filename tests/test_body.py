"""Skinned body (mannequin-x wooden mesh, SMPL-X files) and joints → body fitting."""

import dataclasses

import jax
import jax.numpy as jnp
import mannequin
import numpy as np
import pytest
from jax.test_util import check_grads
from scipy.spatial.transform import Rotation

from jaxmotion.body import (
    BodyFit,
    body_forward,
    fit_joints_to_body,
    load_mannequin,
    load_smplx,
    shaped_rest,
    shaped_rest_host,
    vertex_normals,
)
from jaxmotion.body.priors import (
    JOINT_LIMITS_DEG,
    joint_limit_excess,
    limit_angles,
    rotation_from_limit_angles,
)
from jaxmotion.geometry import PARENTS, axis_angle_to_matrix, rest_joints, smplx_joints

F32 = jnp.float32
# Jitted once and shared by the tests (eager dispatch and repeated compiles dominate
# the run time of small tests on CPU).
_forward = jax.jit(body_forward, static_argnames="normals")
_smplx_joints = jax.jit(smplx_joints)
_from_angles = jax.jit(rotation_from_limit_angles)
_angles_and_excess = jax.jit(lambda rot: (limit_angles(rot), joint_limit_excess(rot)))


def _random_params(seed, t, scale=0.4):
    rng = np.random.default_rng(seed)
    go = rng.normal(size=(t, 3)) * 0.8
    bp = rng.normal(size=(t, 21, 3)) * scale
    tr = rng.normal(size=(t, 3))
    return go, bp, tr


def _mannequin_vertices(go, bp, tr, betas):
    m = mannequin.Mannequin("wooden", shape=np.asarray(betas, np.float32))
    pose = m.rest_pose(batch_dims=(go.shape[0],))
    pose.update(
        pelvis_rotation=go.astype(np.float32),  # SMPL-X global_orient: about the pelvis
        body_pose=bp.astype(np.float32),
        global_translation=tr.astype(np.float32),
    )
    return np.asarray(m.vertices(pose))


# --------------------------------------------------------------------------- mannequin


@pytest.fixture(scope="module")
def wooden():
    return load_mannequin()


@pytest.fixture(scope="module")
def posed(wooden):
    go, bp, tr = _random_params(0, 3)
    betas = np.random.default_rng(1).normal(size=10) * 0.7
    out = _forward(wooden, go, bp, tr, betas)
    return (go, bp, tr, betas), out


def test_mannequin_parity_at_neutral_shape(wooden):
    go, bp, tr = _random_params(2, 3, scale=0.6)
    out = _forward(wooden, go, bp, tr, np.zeros(10))
    ref = _mannequin_vertices(go, bp, tr, np.zeros(10))
    assert out.vertices.shape == ref.shape == (3, wooden.num_vertices, 3)
    np.testing.assert_allclose(np.asarray(out.vertices), ref, atol=1e-4)


def test_shaped_rest_host_equals_shaped_rest(wooden):
    betas = np.random.default_rng(3).normal(size=7)  # fewer than the model's 10
    for b in (None, betas):
        for got, want in zip(shaped_rest_host(wooden, b), shaped_rest(wooden, b), strict=True):
            assert got.dtype == np.float64
            np.testing.assert_allclose(got, np.asarray(want), atol=1e-5)
    with pytest.raises(ValueError, match="11 coefficients"):
        shaped_rest_host(wooden, np.zeros(11))


def test_mannequin_parity_other_shapes(wooden, posed):
    (go, bp, tr, betas), out = posed
    ref = _mannequin_vertices(go, bp, tr, betas)
    # The neutral model reshapes linearly around betas = 0: sub-millimetre here.
    np.testing.assert_allclose(np.asarray(out.vertices), ref, atol=1e-3)
    # Anchored at these betas the mesh is exact.
    exact = _forward(load_mannequin(betas), go, bp, tr, betas).vertices
    np.testing.assert_allclose(np.asarray(exact), ref, atol=1e-4)


def test_joints_equal_smplx_joints(posed):
    (go, bp, tr, betas), out = posed
    ref = smplx_joints(F32(go), F32(bp), F32(tr), F32(betas))
    np.testing.assert_allclose(np.asarray(out.joints), np.asarray(ref), atol=1e-5)


def _winding_number(points, verts, faces):
    """Generalised winding number (Van Oosterom–Strackee solid angles), float64 numpy."""
    tri = verts[faces][None] - points[:, None, None, :]  # [P, F, 3, 3]
    a, b, c = tri[..., 0, :], tri[..., 1, :], tri[..., 2, :]
    la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
    det = np.einsum("pfi,pfi->pf", a, np.cross(b, c))
    dot = lambda x, y: np.einsum("pfi,pfi->pf", x, y)  # noqa: E731
    den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb
    return np.arctan2(det, den).sum(-1) / (2 * np.pi)


def test_normals_unit_and_outward(wooden, posed):
    _, out = posed
    n = np.asarray(out.vertex_normals)
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-5)
    v = np.asarray(out.vertices[0], np.float64)
    faces = np.asarray(wooden.faces)
    # Outward: stepping 0.2 mm along the normal leaves the (watertight, possibly
    # self-overlapping) body, i.e. the winding number drops by one across the surface.
    sub = np.random.default_rng(0).choice(len(v), 120, replace=False)
    p, q = v[sub], n[0, sub]
    probes = np.concatenate([p - 2e-4 * q, p + 2e-4 * q])
    jump = np.concatenate([_winding_number(x, v, faces) for x in np.split(probes, 8)])
    jump = jump[:120] - jump[120:]
    assert np.mean(jump > 0.5) >= 0.95
    assert np.mean(jump < -0.5) <= 0.01
    # ... and the mesh encloses a body-sized positive volume.
    tri = v[faces]
    volume = np.einsum("fi,fi->f", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
    assert 0.04 < volume < 0.12


# --------------------------------------------------------------------------- SMPL-X files


def _fake_smplx(seed=0, v=160, f=300):
    """A small random mesh with the keys and kinematic tree of an SMPL-X model file."""
    rng = np.random.default_rng(seed)
    parents = list(PARENTS) + [15, 15, 15]  # jaw, eyes
    for wrist in (20, 21):
        for _ in range(5):
            base = len(parents)
            parents += [wrist, base, base + 1]
    j = len(parents)
    assert j == 55
    joints = np.zeros((j, 3))
    joints[:22] = np.asarray(rest_joints())
    for k in range(22, j):
        joints[k] = joints[parents[k]] + rng.normal(size=3) * 0.03
    owner = rng.integers(0, j, size=v)
    v_template = joints[owner] + rng.normal(size=(v, 3)) * 0.04
    jreg = np.zeros((j, v))
    for k in range(j):
        pick = rng.choice(v, 4, replace=False)
        jreg[k, pick] = rng.dirichlet(np.ones(4))
    weights = np.zeros((v, j))
    for i in range(v):
        pick = np.unique(np.concatenate([[owner[i]], rng.integers(0, j, size=2)]))
        weights[i, pick] = rng.dirichlet(np.ones(len(pick)))
    kintree = np.stack([np.array([2**32 - 1] + parents[1:], np.int64), np.arange(j)])
    return {
        "v_template": v_template.astype(np.float32),
        "shapedirs": (rng.normal(size=(v, 3, 20)) * 0.01).astype(np.float32),
        "J_regressor": jreg.astype(np.float32),
        "weights": weights.astype(np.float32),
        "kintree_table": kintree,
        "posedirs": (rng.normal(size=(v, 3, (j - 1) * 9)) * 0.01).astype(np.float32),
        "f": rng.integers(0, v, size=(f, 3)).astype(np.uint32),
    }


def _smplx_lbs_numpy(data, go, bp, tr, betas):
    """Reference SMPL-X LBS for one frame (float64, explicit 4x4 transforms, as in smplx)."""
    parents = data["kintree_table"][0].astype(np.int64)
    j = parents.shape[0]
    v = data["v_template"] + data["shapedirs"][..., :10].astype(np.float64) @ betas
    jr = data["J_regressor"].astype(np.float64) @ v
    aa = np.zeros((j, 3))
    aa[0], aa[1:22] = go, bp
    rot = Rotation.from_rotvec(aa).as_matrix()
    feat = (rot[1:] - np.eye(3)).reshape(-1)
    v = v + data["posedirs"].astype(np.float64) @ feat
    g = [None] * j
    for k in range(j):
        t = np.eye(4)
        t[:3, :3] = rot[k]
        t[:3, 3] = jr[k] if k == 0 else jr[k] - jr[parents[k]]
        g[k] = t if k == 0 else g[parents[k]] @ t
    g = np.stack(g)
    joints = g[:, :3, 3] + tr
    a = g.copy()
    a[:, :3, 3] -= np.einsum("kab,kb->ka", g[:, :3, :3], jr)
    blend = np.einsum("vk,kab->vab", data["weights"].astype(np.float64), a)
    verts = np.einsum("vab,vb->va", blend[:, :3, :3], v) + blend[:, :3, 3] + tr
    return verts, joints[:22]


def test_smplx_file_lbs_matches_numpy(tmp_path):
    data = _fake_smplx()
    np.savez(tmp_path / "SMPLX_FAKE.npz", **data)
    model = load_smplx(tmp_path / "SMPLX_FAKE.npz")
    assert model.kind == "smplx" and model.num_joints == 55 and model.posedirs.shape[-1] == 189
    go, bp, tr = _random_params(3, 2, scale=0.5)
    betas = np.random.default_rng(4).normal(size=10)
    out = _forward(model, go, bp, tr, betas)
    for t in range(2):
        ref_v, ref_j = _smplx_lbs_numpy(data, go[t], bp[t], tr[t], betas)
        np.testing.assert_allclose(np.asarray(out.vertices[t]), ref_v, atol=1e-5)
        np.testing.assert_allclose(np.asarray(out.joints[t]), ref_j, atol=1e-5)
    # The same model from a mapping, and the fitting skeleton it exposes.
    assert np.allclose(load_smplx(data).j_template, model.j_template)
    sk = model.skeleton()
    np.testing.assert_allclose(sk.rest, data["J_regressor"][:22] @ data["v_template"], atol=1e-5)


def test_smplx_file_rejects_other_trees():
    data = _fake_smplx()
    data["kintree_table"] = data["kintree_table"].copy()
    data["kintree_table"][0, 4] = 2  # knee hanging from the wrong hip
    with pytest.raises(ValueError, match="SMPL-X's body tree"):
        load_smplx(data)


def test_lbs_gradient_wrt_pose(wooden):
    """Forward- and reverse-mode gradients of the skinned vertices (float64), on a
    subset of the wooden mesh given random pose-corrective blend shapes too."""
    idx = np.linspace(0, wooden.num_vertices - 1, 24).astype(int)
    posedirs = np.random.default_rng(6).normal(size=(24, 3, 21 * 9)) * 0.01
    small = dataclasses.replace(
        wooden,
        v_template=wooden.v_template[idx],
        shapedirs=wooden.shapedirs[idx],
        weights=wooden.weights[idx],
        posedirs=jnp.asarray(posedirs, F32),
        faces=jnp.zeros((0, 3), jnp.int32),
    )
    go, bp, tr = _random_params(5, 1, scale=0.3)
    with jax.enable_x64(True):
        m64 = small.astype(jnp.float64)

        @jax.jit
        def verts(go, bp, tr):
            return body_forward(m64, go, bp, tr, normals=False).vertices

        args = tuple(jnp.asarray(x[0], jnp.float64) for x in (go, bp, tr))
        check_grads(verts, args, order=1, modes=("fwd", "rev"), atol=1e-6, rtol=1e-6)


def test_vertex_normals_of_a_cube():
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], np.float32)
    faces = np.array(
        [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
         [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]
    )  # fmt: skip
    n = np.asarray(vertex_normals(jnp.asarray(corners), jnp.asarray(faces)))
    expected = (corners - 0.5) / np.linalg.norm(corners - 0.5, axis=-1, keepdims=True)
    # area weighting: each corner touches 1 or 2 triangles per face; the sum still points out
    assert np.all(np.einsum("vi,vi->v", n, expected) > 0.8)


# --------------------------------------------------------------------------- priors


def test_limit_angles_round_trip_and_penalty():
    rng = np.random.default_rng(0)
    lo, hi = np.radians(JOINT_LIMITS_DEG[..., 0]), np.radians(JOINT_LIMITS_DEG[..., 1])
    ang = lo + (hi - lo) * rng.uniform(size=(60, 21, 3))
    # The last frame: a knee bent 20° backwards and an elbow bent 32° the wrong way.
    ang[-1] = 0.0
    ang[-1, 3, 0] = np.radians(-28)  # l_knee x: the range starts at -8°
    ang[-1, 17, 0] = np.radians(40)  # l_elbow y (first, YZX): the range ends at 8°
    back, excess = _angles_and_excess(_from_angles(F32(ang)))
    np.testing.assert_allclose(np.asarray(back), ang, atol=1e-4)
    excess = np.degrees(np.asarray(excess))
    assert excess[:-1].max() < 1e-2
    np.testing.assert_allclose([excess[-1, 3, 0], excess[-1, 17, 0]], [20.0, 32.0], atol=1e-3)
    assert np.count_nonzero(excess[-1] > 1e-3) == 2
    identity = jnp.tile(jnp.eye(3), (21, 1, 1))
    grad = jax.jit(jax.grad(lambda r: joint_limit_excess(r).sum()))(identity)
    assert bool(jnp.all(jnp.isfinite(grad)))


# --------------------------------------------------------------------------- fitting


def synthetic_motion(seed, t=60, fps=30.0, frac=0.6):
    """Smooth random motion inside the joint limits: SMPL-X (global_orient, body_pose, transl)."""
    rng = np.random.default_rng(seed)
    time = np.arange(t) / fps
    lo, hi = JOINT_LIMITS_DEG[..., 0], JOINT_LIMITS_DEG[..., 1]
    mid, half = (lo + hi) / 2, (hi - lo) / 2 * frac
    freq = rng.uniform(0.2, 1.2, size=(2, 21, 3))
    phase = rng.uniform(0, 2 * np.pi, size=(2, 21, 3))
    wave = rng.uniform(-0.5, 0.5, size=(21, 3)) + sum(
        amp * np.sin(2 * np.pi * freq[k] * time[:, None, None] + phase[k])
        for k, amp in enumerate((0.3, 0.2))
    )
    ang = np.radians(mid + half * np.clip(wave, -1, 1))
    rot = np.asarray(_from_angles(F32(ang)), np.float64)
    bp = Rotation.from_matrix(rot.reshape(-1, 3, 3)).as_rotvec().reshape(t, 21, 3)
    heading = rng.uniform(-np.pi, np.pi) + 0.5 * np.sin(2 * np.pi * 0.3 * time)
    sway = np.stack(
        [0.15 * np.sin(2 * np.pi * 0.4 * time + 1), 0.1 * np.sin(2 * np.pi * 0.5 * time),
         np.zeros(t)], 1,
    )  # fmt: skip
    root = (
        Rotation.from_euler("z", (heading + np.pi / 2)[:, None])
        * Rotation.from_euler("x", 90, degrees=True)  # stand up: SMPL-X y-up -> z-up
        * Rotation.from_rotvec(sway)
    )
    tr = np.stack([0.8 * time, 0.3 * np.sin(time), 0.9 + 0.05 * np.sin(3 * time)], 1)
    return root.as_rotvec(), bp, tr + rng.normal(size=3)


def _motion_joints(seed, noise=0.0):
    go, bp, tr = synthetic_motion(seed)
    clean = _smplx_joints(F32(go), F32(bp), F32(tr))
    key = jax.random.key(seed)
    return clean, clean + noise * jax.random.normal(key, clean.shape)


FIT_ITERS = 200


@pytest.fixture(scope="module")
def noisy_fit():
    clean, noisy = _motion_joints(10, noise=0.01)
    return clean, noisy, fit_joints_to_body(noisy, iters=FIT_ITERS)


def test_fit_recovers_synthetic_motion(noisy_fit):
    clean, noisy, fit = noisy_fit
    assert isinstance(fit, BodyFit)
    assert fit.body_pose.shape == (60, 21, 3) and fit.global_orient.shape == (60, 3)
    assert fit.betas.shape == (10,) and fit.joint_error.shape == (60, 22)
    err_clean = float(jnp.linalg.norm(fit.joints - clean, axis=-1).mean())
    assert err_clean < 0.02  # below the noise (1 cm per axis ≈ 1.6 cm per joint)
    assert float(fit.mean_error) < 0.02
    # jaxopt does the work: the analytic start is far worse on noisy joints.
    assert float(fit.objective_final) < 0.2 * float(fit.objective_init)
    # The parameters are SMPL-X's: smplx_joints reproduces the fitted joints.
    again = _smplx_joints(fit.global_orient, fit.body_pose, fit.transl, fit.betas)
    np.testing.assert_allclose(np.asarray(again), np.asarray(fit.joints), atol=1e-4)
    # ... and they stay inside the joint limits.
    excess = np.degrees(np.asarray(_angles_and_excess(axis_angle_to_matrix(fit.body_pose))[1]))
    assert excess.max() < 3.0


def test_fit_batched_equals_per_sequence(noisy_fit):
    clean_a, noisy_a, fit_a = noisy_fit
    clean_b, _ = _motion_joints(11)
    batch = fit_joints_to_body(jnp.stack([noisy_a, clean_b]), iters=FIT_ITERS)
    fit_b = fit_joints_to_body(clean_b, iters=FIT_ITERS)
    assert batch.joints.shape == (2, 60, 22, 3) and batch.mean_error.shape == (2,)
    for i, single in enumerate((fit_a, fit_b)):
        # Equal up to float32 round-off (batched kernels sum in another order), which
        # 200 iterations of a non-convex problem amplify to a fraction of a millimetre.
        for field in ("joints", "transl"):
            np.testing.assert_allclose(
                np.asarray(getattr(batch, field)[i]), np.asarray(getattr(single, field)), atol=2e-3
            )
        assert abs(float(batch.mean_error[i]) - float(single.mean_error)) < 5e-4
    # Clean joints of the fitting skeleton are matched to well under a millimetre.
    assert float(fit_b.mean_error) < 1e-3
    assert float(jnp.linalg.norm(fit_b.joints - clean_b, axis=-1).max()) < 0.005


def test_fit_fills_masked_frames():
    clean, noisy = _motion_joints(12)
    mask = np.ones(60)
    mask[25:33] = 0
    broken = noisy.at[25:33].set(0.0)  # garbage in the masked frames
    fit = fit_joints_to_body(broken, mask=mask, iters=FIT_ITERS)
    err = np.asarray(jnp.linalg.norm(fit.joints - clean, axis=-1))
    assert err[mask > 0].mean() < 0.005
    assert err[mask == 0].mean() < 0.05  # interpolated through the gap
    assert float(fit.mean_error) < 0.005  # statistics over valid frames only


@pytest.mark.slow
def test_fit_betas_recovers_bone_lengths():
    go, bp, tr = synthetic_motion(13)
    betas = np.random.default_rng(13).normal(size=10) * 1.0
    joints = smplx_joints(F32(go), F32(bp), F32(tr), F32(betas))
    neutral = fit_joints_to_body(joints, iters=300)
    shaped = fit_joints_to_body(joints, iters=300, fit_betas=True)
    assert float(shaped.mean_error) < 0.005
    assert float(shaped.mean_error) < float(neutral.mean_error)
    r_fit, r_true = rest_joints(shaped.betas), rest_joints(F32(betas))
    par = np.array(PARENTS[1:])
    bone = lambda r: jnp.linalg.norm(r[1:] - r[par], axis=-1)  # noqa: E731
    assert float(jnp.abs(bone(r_fit) - bone(r_true)).max()) < 0.01


@pytest.mark.slow
def test_fit_long_sequence_batch():
    seqs = [_motion_joints(20 + k, noise=0.005)[1] for k in range(2)]
    seqs = [jnp.concatenate([s, s[::-1]]) for s in seqs]  # 120 frames
    fit = fit_joints_to_body(jnp.stack(seqs), iters=300)
    assert fit.joints.shape == (2, 120, 22, 3)
    assert float(fit.mean_error.max()) < 0.02


def test_mannequin_shape_basis_is_kept_next_to_the_compilation_cache(tmp_path):
    from jaxmotion.body import model as M

    b0 = np.zeros(10)
    fresh = M.mannequin_shape_basis(b0, cache_root=None)
    first = M.mannequin_shape_basis(b0, cache_root=tmp_path)
    files = list((tmp_path / "body").glob("mannequin-*.npz"))
    assert len(files) == 1
    again = M.mannequin_shape_basis(b0, cache_root=tmp_path)  # read back from the file
    for a, b, c in zip(fresh, first, again, strict=True):
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(a, c)
    files[0].write_bytes(b"damaged")  # a damaged file is rebuilt
    np.testing.assert_array_equal(M.mannequin_shape_basis(b0, cache_root=tmp_path)[1], fresh[1])
    assert np.load(files[0])["v0"].shape == fresh[0].shape
