"""SMPL-X skeleton: calibration, shape space, forward kinematics vs a numpy brute force."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from jax.test_util import check_grads
from scipy.spatial.transform import Rotation

from jaxmotion.geometry import skeleton as S
from jaxmotion.geometry.rotations import axis_angle_to_matrix, matrix_to_axis_angle


def fk_numpy(local_rot, transl, rest):
    """Reference FK with explicit 4x4 homogeneous transforms (float64)."""
    g = [None] * 22
    for j in range(22):
        t = np.eye(4)
        t[:3, :3] = local_rot[j]
        p = S.PARENTS[j]
        t[:3, 3] = rest[j] if p < 0 else rest[j] - rest[p]
        g[j] = t if p < 0 else g[p] @ t
    return np.stack([gj[:3, 3] for gj in g]) + transl


def test_names_parents_and_mirror():
    assert len(S.JOINT_NAMES) == len(S.PARENTS) == S.NUM_JOINTS == 22
    assert all(S.PARENTS[j] < j for j in range(1, 22))
    perm = np.array(S.MIRROR_PERMUTATION)
    assert np.all(perm[perm] == np.arange(22))
    assert S.JOINT_NAMES[perm[S.JOINT_NAMES.index("l_wrist")]] == "r_wrist"
    assert perm[S.JOINT_NAMES.index("neck")] == S.JOINT_NAMES.index("neck")


def test_rest_joints_host_equals_rest_joints():
    betas = np.random.default_rng(0).normal(size=6)
    for b in (None, betas):
        got = S.rest_joints_host(b)
        assert got.dtype == np.float64 and got.shape == (22, 3)
        np.testing.assert_allclose(got, np.asarray(S.rest_joints(b)), atol=1e-5)
    with pytest.raises(ValueError, match="shape directions"):
        S.rest_joints_host(np.zeros(S.NUM_BETAS + 1))


def test_neutral_rest_is_a_plausible_human():
    rest = np.asarray(S.rest_joints())
    assert rest.shape == (22, 3)
    height = rest[15, 1] - min(rest[10, 1], rest[11, 1])  # head joint above the toes (y up)
    assert 1.3 < height < 1.7
    assert rest[1, 0] > 0 > rest[2, 0]  # left hip at +x in the SMPL-X frame
    np.testing.assert_allclose(rest[[1, 4, 7]][:, 1], rest[[2, 5, 8]][:, 1], atol=0.02)


def test_shape_space_is_linear_and_changes_bone_lengths():
    rng = np.random.default_rng(0)
    b1, b2 = rng.normal(size=10), rng.normal(size=10)
    r0, r1, r2 = (np.asarray(S.rest_joints(b)) for b in (None, b1, b2))
    r12 = np.asarray(S.rest_joints(b1 + b2))
    np.testing.assert_allclose(r12 - r0, (r1 - r0) + (r2 - r0), atol=1e-5)
    tall = np.asarray(S.rest_joints(np.array([-2.0] + [0] * 9)))
    short = np.asarray(S.rest_joints(np.array([2.0] + [0] * 9)))
    assert abs(np.ptp(tall[:, 1]) - np.ptp(short[:, 1])) > 0.05
    # batched betas
    assert S.rest_joints(jnp.zeros((4, 10))).shape == (4, 22, 3)


@given(st.integers(0, 10_000))
def test_forward_kinematics_matches_numpy(seed):
    rng = np.random.default_rng(seed)
    rot = Rotation.random(22, random_state=seed).as_matrix()
    transl = rng.normal(size=3)
    rest = np.asarray(S.rest_joints(rng.normal(size=10)), np.float64)
    got = S.forward_kinematics(jnp.asarray(rot, jnp.float32), jnp.asarray(transl, jnp.float32), rest)
    np.testing.assert_allclose(got, fk_numpy(rot, transl, rest), atol=2e-5)
    # bone lengths are preserved by construction
    np.testing.assert_allclose(S.bone_lengths(got), S.bone_lengths(jnp.asarray(rest)), atol=2e-5)


def test_rest_pose_and_smplx_translation_convention():
    rest = S.rest_joints()
    eye = jnp.broadcast_to(jnp.eye(3), (22, 3, 3))
    np.testing.assert_allclose(S.forward_kinematics(eye, jnp.zeros(3)), rest, atol=1e-7)
    # the global orientation rotates about the rest pelvis; transl is added after
    rz = jnp.asarray(Rotation.from_euler("y", 1.0).as_matrix(), jnp.float32)
    j = S.forward_kinematics(eye.at[0].set(rz), jnp.array([1.0, 2.0, 3.0]))
    np.testing.assert_allclose(j[0], rest[0] + jnp.array([1.0, 2.0, 3.0]), atol=1e-6)


def test_smplx_joints_and_upright_orientation():
    for heading in (0.0, 0.7, -2.0):
        go = matrix_to_axis_angle(S.upright_orientation(heading))
        j = np.asarray(S.smplx_joints(go, jnp.zeros((21, 3)), jnp.zeros(3)))
        assert j[15, 2] - j[0, 2] > 0.5  # head above pelvis: z is up
        feet_fwd = 0.5 * (j[10] + j[11]) - 0.5 * (j[7] + j[8])  # toes ahead of the ankles
        fwd = np.array([np.cos(heading), np.sin(heading)])
        assert feet_fwd[:2] @ fwd > 0.05
        left = j[1] - j[2]  # left hip is to the left of the facing direction
        assert np.cross(np.append(fwd, 0), left)[2] > 0
    # batch over frames
    t = 5
    j = S.smplx_joints(jnp.zeros((t, 3)), jnp.zeros((t, 21, 3)), jnp.zeros((t, 3)), jnp.zeros(10))
    assert j.shape == (t, 22, 3)


def test_fk_jit_vmap_and_gradients():
    rng = np.random.default_rng(3)
    aa = jnp.asarray(rng.normal(scale=0.3, size=(4, 22, 3)), jnp.float32)
    tr = jnp.asarray(rng.normal(size=(4, 3)), jnp.float32)
    f = jax.jit(jax.vmap(lambda a, t: S.forward_kinematics(axis_angle_to_matrix(a), t)))
    np.testing.assert_allclose(
        f(aa, tr), S.forward_kinematics(axis_angle_to_matrix(aa), tr), atol=1e-5
    )
    with jax.enable_x64(True):
        rest = jnp.asarray(S.rest_joints(), jnp.float64)

        def fk(a, t):
            return S.forward_kinematics(axis_angle_to_matrix(a), t, rest)

        check_grads(fk, (jnp.asarray(aa[0], jnp.float64), jnp.asarray(tr[0], jnp.float64)), order=1)


def test_bad_shapes_are_explained():
    import pytest

    with pytest.raises(ValueError, match=r"\[\.\.\., 22, 3, 3\]"):
        S.forward_kinematics(jnp.zeros((21, 3, 3)), jnp.zeros(3))
    with pytest.raises(ValueError, match="betas has 12"):
        S.rest_joints(jnp.zeros(12))


def test_kinematic_chain_places_the_same_joints_as_the_whole_body():
    feet = (7, 8, 10, 11)
    chain = S.kinematic_chain(feet)
    assert chain == (0, 1, 2, 4, 5, 7, 8, 10, 11)  # pelvis, hips, knees, ankles, feet
    assert S.kinematic_chain(range(22)) == tuple(range(22))
    assert S.kinematic_chain([15]) == (0, 3, 6, 9, 12, 15)  # the head hangs from the spine
    rng = np.random.default_rng(0)
    rot = Rotation.random(5 * 22, random_state=1).as_matrix().reshape(5, 22, 3, 3)
    transl, rest = rng.normal(size=(5, 3)), np.asarray(S.rest_joints(rng.normal(size=10)))
    whole, whole_rot = S.forward_kinematics_with_rotations(
        jnp.asarray(rot, jnp.float32), jnp.asarray(transl, jnp.float32), rest)
    part, part_rot = S.forward_kinematics_with_rotations(
        jnp.asarray(rot[:, chain], jnp.float32), jnp.asarray(transl, jnp.float32), rest, chain)
    np.testing.assert_array_equal(part, np.asarray(whole)[:, chain])
    np.testing.assert_array_equal(part_rot, np.asarray(whole_rot)[:, chain])
    for j in chain:  # against the homogeneous-transform reference too
        np.testing.assert_allclose(part[0, chain.index(j)], fk_numpy(rot[0], transl[0], rest)[j],
                                   atol=2e-5)


def test_a_bad_chain_is_explained():
    with pytest.raises(ValueError, match="not a kinematic chain"):
        S.forward_kinematics_with_rotations(jnp.zeros((2, 3, 3)), jnp.zeros(3), None, (0, 7))
    with pytest.raises(ValueError, match=r"\[\.\.\., 3, 3, 3\]"):
        S.forward_kinematics_with_rotations(jnp.zeros((2, 3, 3)), jnp.zeros(3), None, (0, 1, 4))
    with pytest.raises(ValueError, match="joint index 22"):
        S.kinematic_chain([22])
