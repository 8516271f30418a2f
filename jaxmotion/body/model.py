"""A differentiable skinned body: the SMPL-X kinematic tree with linear blend skinning.

One set of pure functions poses two kinds of mesh:

- **the mannequin-x "wooden" mesh** (:func:`load_mannequin`; Apache-2.0 assets
  shipped in the ``mannequin-x`` package, 24,256 vertices, 48,396 faces, 54
  joints = the 22 SMPL-X body joints, two hand roots and 30 finger joints). Its
  skinning is reproduced exactly: mannequin-x keeps the 4 strongest of the 8
  stored weights per vertex (renormalised), binds rigid parts (the ball joints)
  to one joint, and poses ``v = Σ_k w_k (R_k (v_bind − b_k) + p_k)`` with the
  bind positions ``b`` = its calibrated SMPL-X rest joints.
- **a user's own SMPL-X model** (:func:`load_smplx`, from the official ``.npz``):
  the same LBS with SMPL-X's shape blend shapes, joint regressor and the
  pose-corrective blend shapes of the 21 body joints.

Parameters are SMPL-X's (``global_orient [T,3]``, ``body_pose [T,21,3]``,
``transl [T,3]``, ``betas [B]``, axis-angle, radians, metres) and the outputs are
in the jaxmotion world frame: the rest mesh is SMPL-X's (y up, facing +z) and,
exactly as for :func:`jaxmotion.geometry.smplx_joints`, the global orientation
rotates it about the rest pelvis and ``transl`` is added after (in mannequin-x's
own API: ``pelvis_rotation=global_orient``, ``global_translation=transl`` and no
``global_rotation``, which would turn the body about the origin); a global
orientation from :func:`jaxmotion.geometry.upright_orientation` stands it up in the
z-up world. ``joints`` equals ``smplx_joints`` for the same parameters (for the
mannequin; a user's SMPL-X model uses its own regressed rest joints).

Joints other than the 22 body joints (hands, fingers; SMPL-X's jaw and eyes)
follow their parents with a fixed local rotation: the mannequin's fingers hold
SMPL-X's relaxed hand mean (mannequin-x's default, ``flat_hand_mean=False`` with
zero hand pose); SMPL-X's hands are flat, jaw and eyes closed/forward and the
expression neutral (``smplx`` with ``flat_hand_mean=True`` and zero hand, jaw,
eye and expression parameters). SMPL-X's pose-corrective blend shapes are
applied for the 21 body joints; those of the other joints vanish because their
rotations are the identity.

Shape: SMPL-X's betas act linearly on its mesh and joints, as in SMPL-X.
mannequin-x reshapes its wooden geometry non-linearly (per-bone similarity fits,
head box fit, forefoot re-levelling, symmetrisation) while its bind joints stay
exactly linear in the betas. We store the mesh at an *anchor* shape (betas = 0
by default, or any ``betas`` given to :func:`load_mannequin`) together with its
finite-difference shape Jacobian there: posing is exact (to float32 rounding)
at the anchor and a first-order approximation elsewhere (measured with random
betas around the anchor: worst vertex ≤ 0.3 mm for coefficients of standard
deviation 1; ≤ 1.2 cm worst vertex and ~1.5 mm mean for standard deviation 2-3,
where mannequin-x's forefoot re-levelling, a max over vertices, kicks in), and
the mesh is differentiable in the betas. Build the model at the betas you render
with for exact geometry. Joints are exact for all betas.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxmotion._npio import load_npz
from jaxmotion.geometry.rotations import axis_angle_to_matrix
from jaxmotion.geometry.skeleton import (
    NUM_BETAS,
    NUM_JOINTS,
    PARENTS,
    SMPLX_JOINT_NAMES,
    SMPLX_PARENTS,
    Skeleton,
)

__all__ = [
    "BodyModel",
    "BodyOutput",
    "body_forward",
    "forward_tree",
    "joint_names",
    "lbs",
    "load_mannequin",
    "load_smplx",
    "local_rotations",
    "shaped_rest",
    "vertex_normals",
]

_NUM_BODY_POSE = NUM_JOINTS - 1  # 21 joints in SMPL-X's body_pose
_MANNEQUIN_INFLUENCES = 4  # mannequin-x skins with the 4 strongest weights per vertex
_FD_STEP = 0.5  # finite-difference step in betas for the mannequin's shape Jacobian
# Full float32 matmuls: on GPUs the default may use TF32 (~1e-3 relative), which would
# cost millimetres on posed vertices. A no-op on CPU.
_HI = jax.lax.Precision.HIGHEST


@functools.partial(
    jax.tree_util.register_dataclass,
    data_fields=[
        "v_template", "shapedirs", "j_template", "j_shapedirs", "weights", "faces",
        "posedirs", "fixed_pose",
    ],
    meta_fields=["parents", "kind"],
)  # fmt: skip
@dataclasses.dataclass(frozen=True)
class BodyModel:
    """Arrays of a skinned body (a pytree: pass it through ``jit``/``vmap`` freely).

    Attributes:
      v_template: ``[V, 3]`` rest vertices at betas = 0 of the linear shape space
        (SMPL-X frame, metres): ``v_template + shapedirs @ betas``.
      shapedirs: ``[V, 3, B]`` vertex offsets per unit beta.
      j_template: ``[J, 3]`` rest (bind) joints at betas = 0.
      j_shapedirs: ``[J, 3, B]`` joint offsets per unit beta.
      weights: ``[V, J]`` skinning weights, rows sum to 1 (dense: J is small).
      faces: ``[F, 3]`` int32 triangles, counter-clockwise seen from outside.
      posedirs: ``[V, 3, P]`` pose-corrective blend shapes over the body joints'
        ``(R_j − I)`` entries (P = 21·9, joint-major, row-major 3×3), or P = 0.
      fixed_pose: ``[J, 3]`` axis-angle local rotation of every joint that is not
        one of the 22 body joints (zero rows for the body joints).
      parents: parent index of each of the J joints (−1 for the root); the first
        22 are SMPL-X's body tree.
      kind: ``"mannequin"`` or ``"smplx"``.
    """

    v_template: Any
    shapedirs: Any
    j_template: Any
    j_shapedirs: Any
    weights: Any
    faces: Any
    posedirs: Any
    fixed_pose: Any
    parents: tuple[int, ...]
    kind: str

    @property
    def num_vertices(self) -> int:
        return self.v_template.shape[0]

    @property
    def num_joints(self) -> int:
        return len(self.parents)

    @property
    def num_betas(self) -> int:
        return self.shapedirs.shape[-1]

    def skeleton(self) -> Skeleton:
        """The 22-joint body :class:`~jaxmotion.geometry.Skeleton` of this model (host numpy)."""
        return Skeleton(
            rest=np.asarray(self.j_template[:NUM_JOINTS], np.float32),
            shape_dirs=np.asarray(self.j_shapedirs[:NUM_JOINTS], np.float32),
        )

    def astype(self, dtype) -> BodyModel:
        """Copy with every float array cast to ``dtype`` (e.g. float64 for gradient checks)."""
        cast = {
            f: jnp.asarray(getattr(self, f), dtype)
            for f in ("v_template", "shapedirs", "j_template", "j_shapedirs", "weights",
                      "posedirs", "fixed_pose")
        }  # fmt: skip
        return dataclasses.replace(self, **cast)


class BodyOutput(NamedTuple):
    """Posed body in the world frame, metres.

    Attributes:
      vertices: ``[..., V, 3]``.
      vertex_normals: ``[..., V, 3]`` unit, area-weighted, outward.
      joints: ``[..., 22, 3]`` the SMPL-X body joints.
    """

    vertices: jnp.ndarray
    vertex_normals: jnp.ndarray
    joints: jnp.ndarray


def _check_tree(parents: tuple[int, ...]) -> None:
    if tuple(parents[:NUM_JOINTS]) != PARENTS:
        raise ValueError(
            f"the first 22 joints must be SMPL-X's body tree {PARENTS}, got {parents[:NUM_JOINTS]}"
        )
    if any(not 0 <= p < j for j, p in enumerate(parents) if j > 0):
        raise ValueError("every joint's parent must come before it in the joint order")


def _known_trees() -> dict[tuple[int, ...], tuple[str | None, ...]]:
    """SMPL-X names of the joints of each joint tree a :class:`BodyModel` can have."""
    hands = SMPLX_JOINT_NAMES[25:]
    # SMPL+H's 52 joints: the body, then the 30 finger joints (no jaw, no eyes)
    smplh = PARENTS + tuple(p - 3 if p > 21 else p for p in SMPLX_PARENTS[25:])
    # the mannequin's 54: the body, a hand root on each wrist (at the wrist, never turned
    # on its own, no skin weight: SMPL-X has no such joint), then the fingers on it
    mannequin = PARENTS + (20, 21) + tuple(
        (22 if p == 20 else 23 if p == 21 else p - 1) for p in SMPLX_PARENTS[25:])
    return {
        SMPLX_PARENTS: SMPLX_JOINT_NAMES,
        smplh: SMPLX_JOINT_NAMES[:NUM_JOINTS] + hands,
        mannequin: SMPLX_JOINT_NAMES[:NUM_JOINTS] + (None, None) + hands,
    }


def joint_names(model: BodyModel) -> tuple[str | None, ...]:
    """The SMPL-X name of each of the model's joints (``SMPLX_JOINT_NAMES``: ``pelvis``,
    ``left_hip``, …, ``jaw``, ``left_eye_smplhf``, ``left_index1``, …, ``right_thumb3``).

    Known by the joint tree: SMPL-X's 55 joints, SMPL+H's 52 (no jaw or eyes) and the
    mannequin's 54 (22 body joints, 30 finger joints, no jaw or eyes, and two hand roots
    that sit on the wrists, are never turned and carry no skin: None, SMPL-X has no
    such joint). ValueError for any other tree.
    """
    names = _known_trees().get(tuple(model.parents))
    if names is None:
        raise ValueError(f"no SMPL-X names for a body of {model.num_joints} joints with "
                         f"parents {model.parents}: expected the SMPL-X (55), SMPL+H (52) "
                         "or mannequin (54) joint tree")
    return names


# --------------------------------------------------------------------------- loading


def _mannequin_assets():
    try:
        pkg = resources.files("mannequin")
    except ModuleNotFoundError as err:  # pragma: no cover - dependency missing
        raise ImportError("the wooden body needs 'mannequin-x>=0.3,<0.4'") from err
    with (pkg / "assets" / "wooden.npz").open("rb") as f, load_npz(f) as d:
        wooden = {k: d[k] for k in ("parents", "faces", "skin_joint_indices", "skin_weights",
                                    "skin_rigid_joint_indices")}  # fmt: skip
    with (pkg / "assets" / "smplx_calibration.npz").open("rb") as f, load_npz(f) as d:
        calib = {k: np.asarray(d[k], np.float64) for k in ("joint_rest", "joint_dirs", "hand_mean")}
    return wooden, calib


def _mannequin_weights(wooden: Mapping[str, np.ndarray]) -> np.ndarray:
    """Dense ``[V, J]`` weights exactly as mannequin-x binds its skin (``Mannequin._bind_skin``)."""
    idx = wooden["skin_joint_indices"].astype(np.int64)
    w = wooden["skin_weights"].astype(np.float32)
    strongest = np.argsort(w, axis=1)[:, -_MANNEQUIN_INFLUENCES:]
    idx = np.take_along_axis(idx, strongest, axis=1)
    w = np.take_along_axis(w, strongest, axis=1)
    w = w / w.sum(axis=1, keepdims=True)
    rigid = wooden["skin_rigid_joint_indices"] >= 0
    idx[rigid] = wooden["skin_rigid_joint_indices"][rigid, None]
    w[rigid] = 0.0
    w[rigid, 0] = 1.0
    dense = np.zeros((idx.shape[0], len(wooden["parents"])), np.float64)
    np.add.at(dense, (np.arange(idx.shape[0])[:, None], idx), w)
    return dense


def _mannequin_bind_vertices(m, betas: np.ndarray) -> np.ndarray:
    """The wooden mesh's bind vertices for one shape, through mannequin-x's public API.

    With ``flat_hand_mean=True`` and every parameter zero, each joint sits at its
    bind position with identity rotation, so ``vertices`` returns the bind mesh.
    """
    m.reshape(np.asarray(betas, np.float32))
    return np.asarray(m.vertices(m.rest_pose()), np.float64)


def mannequin_shape_basis(b0: np.ndarray, cache_root=None) -> tuple[np.ndarray, np.ndarray]:
    """Bind vertices ``[V,3]`` at shape ``b0`` and their central-difference shape directions
    ``[V,3,10]`` (21 calls into mannequin-x, about 0.7 s on CPU). When JAX's persistent
    compilation cache is on (the command line and ``jaxmotion.generate`` turn it on), the result
    is kept next to it (``body/``; or under ``cache_root``), keyed by the mannequin-x version,
    the anchor and the step."""
    import hashlib
    import importlib.metadata

    path = None
    root = cache_root or jax.config.jax_compilation_cache_dir
    if root:
        try:
            version = importlib.metadata.version("mannequin-x")
        except importlib.metadata.PackageNotFoundError:  # pragma: no cover - odd install
            version = "unknown"
        key = hashlib.sha256(repr((version, b0.tolist(), _FD_STEP, NUM_BETAS)).encode())
        path = Path(root) / "body" / f"mannequin-{key.hexdigest()[:24]}.npz"
        if path.is_file():
            try:
                with load_npz(path) as d:
                    return d["v0"], d["dirs"]
            except (OSError, ValueError, KeyError):  # damaged: rebuilt and rewritten below
                pass
    import mannequin

    m = mannequin.Mannequin("wooden", flat_hand_mean=True)
    v0 = _mannequin_bind_vertices(m, b0)
    dirs = np.zeros((*v0.shape, NUM_BETAS))
    for i in range(NUM_BETAS):
        e = np.zeros(NUM_BETAS)
        e[i] = _FD_STEP
        dirs[..., i] = (
            _mannequin_bind_vertices(m, b0 + e) - _mannequin_bind_vertices(m, b0 - e)
        ) / (2 * _FD_STEP)
    if path is not None:
        try:
            from jaxmotion._atomic import atomic_open

            path.parent.mkdir(parents=True, exist_ok=True)
            with atomic_open(path, "wb") as f:
                np.savez(f, v0=v0, dirs=dirs)
        except OSError:
            pass  # a read-only cache: rebuilt next time
    return v0, dirs


@functools.lru_cache(maxsize=4)
def _load_mannequin_cached(anchor: tuple[float, ...]) -> BodyModel:
    wooden, calib = _mannequin_assets()
    parents = tuple(int(p) for p in wooden["parents"])
    _check_tree(parents)
    b0 = np.asarray(anchor, np.float64)
    v0, dirs = mannequin_shape_basis(b0)
    num_joints = len(parents)
    fixed = np.zeros((num_joints, 3))
    # Joints 22, 23 (hand roots) are unposed; the 30 finger joints hold the hand mean.
    fixed[num_joints - calib["hand_mean"].shape[0] :] = calib["hand_mean"]
    # converted on the host and device_put: jnp.asarray dispatches an XLA program per array,
    # each compiled anew in every process (~20 ms apiece)
    f32 = lambda x: jax.device_put(np.asarray(x, np.float32))  # noqa: E731
    return BodyModel(
        v_template=f32(v0 - dirs @ b0),  # so that v_template + dirs @ betas is exact at the anchor
        shapedirs=f32(dirs),
        j_template=f32(calib["joint_rest"]),
        j_shapedirs=f32(calib["joint_dirs"][..., :NUM_BETAS]),
        weights=f32(_mannequin_weights(wooden)),
        faces=jax.device_put(np.asarray(wooden["faces"], np.int32)),
        posedirs=f32(np.zeros((v0.shape[0], 3, 0))),
        fixed_pose=f32(fixed),
        parents=parents,
        kind="mannequin",
    )


def load_mannequin(betas=None) -> BodyModel:
    """The mannequin-x wooden body (Apache-2.0 assets of the ``mannequin-x`` package).

    Args:
      betas: ``[10]`` anchor shape at which the mesh is exact (default neutral).
        Other betas passed to :func:`body_forward` use the linearised shape space
        around the anchor (see the module docstring). Joints are exact for all betas.
    Returns:
      a :class:`BodyModel` (cached per anchor; about 0.5 s to build on CPU).
    """
    anchor = np.zeros(NUM_BETAS) if betas is None else np.asarray(betas, np.float64).reshape(-1)
    if anchor.shape != (NUM_BETAS,):
        raise ValueError(f"the mannequin has {NUM_BETAS} shape coefficients, got {anchor.shape}")
    return _load_mannequin_cached(tuple(float(b) for b in anchor))


def load_smplx(source: str | Path | Mapping[str, Any], num_betas: int = NUM_BETAS) -> BodyModel:
    """A user's SMPL-X model from its official ``.npz`` (or a mapping with the same keys).

    Keys used: ``v_template [V,3]``, ``shapedirs [V,3,S]`` (the first ``num_betas``
    are the shape betas; expression directions are ignored), ``J_regressor [J,V]``,
    ``weights [V,J]``, ``kintree_table [2,J]`` (row 0 = parents), ``posedirs
    [V,3,(J−1)·9]`` and ``f [F,3]``. The SMPL-X files themselves are licensed:
    jaxmotion never ships or downloads them.
    """
    required = {"v_template", "shapedirs", "J_regressor", "weights", "kintree_table", "f"}
    if isinstance(source, (str, Path)):
        # Read only the arrays used: official files also hold pickled objects (joint2num).
        with np.load(source, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files if k in required | {"posedirs"}}
    else:
        arrays = dict(source)
    missing = required - set(arrays)
    if missing:
        raise KeyError(f"not an SMPL-X model: missing {sorted(missing)}")
    v = np.asarray(arrays["v_template"], np.float64)
    sd = np.asarray(arrays["shapedirs"], np.float64)
    if sd.shape[-1] < num_betas:
        raise ValueError(f"the model has {sd.shape[-1]} shape directions, asked for {num_betas}")
    sd = sd[..., :num_betas]
    jreg = arrays["J_regressor"]
    jreg = np.asarray(jreg.toarray() if hasattr(jreg, "toarray") else jreg, np.float64)
    kin = np.asarray(arrays["kintree_table"]).astype(np.int64)
    parents = tuple(-1 if j == 0 else int(kin[0, j]) for j in range(kin.shape[1]))
    _check_tree(parents)
    num_joints = len(parents)
    if jreg.shape != (num_joints, v.shape[0]):
        raise ValueError(f"J_regressor must be [{num_joints}, {v.shape[0]}], got {jreg.shape}")
    if np.shape(arrays["weights"]) != (v.shape[0], num_joints):
        raise ValueError(f"weights must be [{v.shape[0]}, {num_joints}]")
    if "posedirs" in arrays:
        pd = np.asarray(arrays["posedirs"], np.float64)
        if pd.ndim == 2:  # [V*3, P] layout of some conversions
            pd = pd.reshape(v.shape[0], 3, -1)
        pd = pd[..., : _NUM_BODY_POSE * 9]
    else:
        pd = np.zeros((v.shape[0], 3, 0))
    # converted on the host and device_put: jnp.asarray dispatches an XLA program per array,
    # each compiled anew in every process (~20 ms apiece)
    f32 = lambda x: jax.device_put(np.asarray(x, np.float32))  # noqa: E731
    return BodyModel(
        v_template=f32(v),
        shapedirs=f32(sd),
        j_template=f32(jreg @ v),
        j_shapedirs=f32(np.einsum("jv,vcb->jcb", jreg, sd)),
        weights=f32(arrays["weights"]),
        faces=jnp.asarray(np.asarray(arrays["f"]).astype(np.int64), jnp.int32),
        posedirs=f32(pd),
        fixed_pose=jnp.zeros((num_joints, 3), jnp.float32),
        parents=parents,
        kind="smplx",
    )


# --------------------------------------------------------------------------- posing


def shaped_rest(model: BodyModel, betas=None) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Rest vertices ``[V,3]`` and bind joints ``[J,3]`` for ``betas [B']`` (B' ≤ B; None = 0)."""
    v, j = model.v_template, model.j_template
    if betas is None:
        return v, j
    betas = jnp.asarray(betas, v.dtype)
    nb = betas.shape[-1]
    if nb > model.num_betas:
        raise ValueError(f"betas has {nb} coefficients, the model {model.num_betas}")
    v = v + jnp.einsum("vcb,b->vc", model.shapedirs[..., :nb], betas, precision=_HI)
    j = j + jnp.einsum("jcb,b->jc", model.j_shapedirs[..., :nb], betas, precision=_HI)
    return v, j


def shaped_rest_host(model: BodyModel, betas=None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`shaped_rest` in NumPy (float64), for exporters: no XLA program is dispatched
    (each eager JAX operation is a compilation in a fresh process)."""
    v, j = np.asarray(model.v_template, np.float64), np.asarray(model.j_template, np.float64)
    if betas is None:
        return v, j
    betas = np.asarray(betas, np.float64).reshape(-1)
    nb = betas.shape[-1]
    if nb > model.num_betas:
        raise ValueError(f"betas has {nb} coefficients, the model {model.num_betas}")
    v = v + np.asarray(model.shapedirs, np.float64)[..., :nb] @ betas
    j = j + np.asarray(model.j_shapedirs, np.float64)[..., :nb] @ betas
    return v, j


def local_rotations(model: BodyModel, global_orient, body_pose) -> jnp.ndarray:
    """Local rotations ``[..., J, 3, 3]`` of every joint from ``[...,3]`` and ``[...,21,3]``."""
    dtype = model.v_template.dtype
    go = jnp.asarray(global_orient, dtype)
    bp = jnp.asarray(body_pose, dtype)
    batch = go.shape[:-1]
    extra = model.num_joints - NUM_JOINTS
    fixed = jnp.broadcast_to(model.fixed_pose[NUM_JOINTS:], (*batch, extra, 3))
    aa = jnp.concatenate([go[..., None, :], bp, fixed], axis=-2)
    return axis_angle_to_matrix(aa)


@functools.lru_cache(maxsize=8)
def _tree_plan(parents: tuple[int, ...]):
    """Static index tables that let FK run one batched step per tree level."""
    num = len(parents)
    depth = [0] * num
    for j in range(1, num):
        depth[j] = depth[parents[j]] + 1
    order = sorted(range(num), key=lambda j: (depth[j], j))  # depth-sorted; levels contiguous
    pos = {j: i for i, j in enumerate(order)}
    levels = []
    for d in range(1, max(depth, default=0) + 1):
        js = [j for j in order if depth[j] == d]
        levels.append((pos[js[0]], pos[js[-1]] + 1, np.array([pos[parents[j]] for j in js])))
    parent_sorted = np.array([0] + [pos[parents[j]] for j in order[1:]])
    # chain[i, k] = 1 when sorted joint k (not the root) is joint i or one of its ancestors.
    chain = np.zeros((num, num), np.float32)
    for j in range(1, num):
        k = j
        while k > 0:
            chain[pos[j], pos[k]] = 1.0
            k = parents[k]
    return np.array(order), np.argsort(order), tuple(levels), parent_sorted, chain


def forward_tree(parents: tuple[int, ...], local_rot, j_rest, transl):
    """Forward kinematics of any joint tree, one batched step per tree level.

    Args:
      parents: parent of each joint (−1 for the root), parents before children.
      local_rot: ``[..., J, 3, 3]`` local rotations (joint 0: global orientation).
      j_rest: ``[J, 3]`` rest joints; transl: ``[..., 3]``.
    Returns:
      joints ``[..., J, 3]`` and global rotations ``[..., J, 3, 3]``; the root
      turns about its rest position and ``transl`` is added after (SMPL-X).

    Same results as the joint-by-joint recursion, but a handful of batched ops
    per level (an unrolled 54-joint recursion takes seconds to compile on CPU).
    """
    # Fresh numpy index arrays per call: jax caches conversions of a *reused* index
    # array, and one cached under float32 breaks a later call under jax.enable_x64.
    order, inverse, levels, parent_sorted, chain = (
        np.array(x) if isinstance(x, np.ndarray) else x for x in _tree_plan(tuple(parents))
    )
    levels = [(lo, hi, np.array(pidx)) for lo, hi, pidx in levels]
    rot = local_rot[..., order, :, :]
    rest = j_rest[order]
    g = rot[..., :1, :, :]
    for lo, hi, pidx in levels:
        child = jnp.matmul(g[..., pidx, :, :], rot[..., lo:hi, :, :], precision=_HI)
        g = jnp.concatenate([g, child], axis=-3)
    # p_i = p_root + Σ over the chain of G_parent(k) (b_k − b_parent(k))
    offsets = rest - rest[parent_sorted]
    bones = jnp.einsum("...jab,jb->...ja", g[..., parent_sorted, :, :], offsets, precision=_HI)
    pos = jnp.einsum("jk,...ka->...ja", jnp.asarray(chain, bones.dtype), bones, precision=_HI)
    pos = pos + (rest[0] + transl)[..., None, :]
    return pos[..., inverse, :], g[..., inverse, :, :]


def lbs(model: BodyModel, local_rot, transl, v_shaped, j_rest) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Linear blend skinning of one frame.

    Args:
      model: the body.
      local_rot: ``[J, 3, 3]`` local joint rotations (joint 0: global orientation).
      transl: ``[3]`` SMPL-X translation, added after the rotation about the rest pelvis.
      v_shaped: ``[V, 3]`` and j_rest: ``[J, 3]`` from :func:`shaped_rest`.
    Returns:
      vertices ``[V, 3]`` and all joints ``[J, 3]``, world frame.

    ``p_j = p_parent + G_parent (b_j − b_parent)``, ``G_j = G_parent R_j``, and each
    vertex moves with ``Σ_j w_vj [G_j | p_j − G_j b_j]`` applied to its rest
    position plus pose correctives ``posedirs · vec(R_j − I)`` (body joints).
    """
    joints, g = forward_tree(model.parents, local_rot, j_rest, transl)
    t = joints - jnp.einsum("jab,jb->ja", g, j_rest, precision=_HI)
    affine = jnp.concatenate([g, t[..., None]], axis=-1).reshape(model.num_joints, 12)
    blended = jnp.matmul(model.weights, affine, precision=_HI).reshape(-1, 3, 4)  # [V, 3, 4]
    if model.posedirs.shape[-1]:
        eye = jnp.eye(3, dtype=local_rot.dtype)
        feat = (local_rot[1:NUM_JOINTS] - eye).reshape(-1)[: model.posedirs.shape[-1]]
        v_shaped = v_shaped + jnp.einsum("vcp,p->vc", model.posedirs, feat, precision=_HI)
    verts = jnp.einsum("vab,vb->va", blended[..., :3], v_shaped, precision=_HI) + blended[..., 3]
    return verts, joints


def vertex_normals(vertices, faces) -> jnp.ndarray:
    """Unit area-weighted vertex normals ``[V, 3]`` of one mesh.

    Each face adds its (unnormalised) cross product ``(v1 − v0) × (v2 − v0)``, whose
    length is twice its area, to its three vertices; the sums are normalised.
    Counter-clockwise faces (seen from outside) give outward normals. Vertices
    in no face get a zero normal.
    """
    tri = vertices[faces]  # [F, 3, 3]
    fn = jnp.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    acc = jnp.zeros_like(vertices)
    for k in range(3):
        acc = acc.at[faces[:, k]].add(fn)
    norm = jnp.sqrt(jnp.sum(acc * acc, axis=-1, keepdims=True))
    return acc / jnp.maximum(norm, jnp.finfo(vertices.dtype).tiny ** 0.5)


def body_forward(
    model: BodyModel,
    global_orient,
    body_pose,
    transl,
    betas=None,
    *,
    normals: bool = True,
) -> BodyOutput:
    """Pose the body for any number of frames.

    Args:
      model: from :func:`load_mannequin` or :func:`load_smplx`.
      global_orient: ``[..., 3]`` axis-angle; body_pose: ``[..., 21, 3]``;
      transl: ``[..., 3]`` metres; betas: ``[B']`` shared by all frames, or None.
      normals: also compute vertex normals (else that field is None).
    Returns:
      :class:`BodyOutput` with ``vertices [..., V, 3]``, ``vertex_normals`` and
      ``joints [..., 22, 3]`` in the world frame.
    """
    dtype = jnp.result_type(global_orient, body_pose, transl, jnp.float32)
    if model.v_template.dtype != dtype:
        model = model.astype(dtype)
    global_orient = jnp.asarray(global_orient, dtype)
    body_pose = jnp.asarray(body_pose, dtype)
    transl = jnp.asarray(transl, dtype)
    if body_pose.shape[-2:] != (_NUM_BODY_POSE, 3):
        raise ValueError(f"body_pose must be [..., 21, 3], got {body_pose.shape}")
    batch = global_orient.shape[:-1]
    v_shaped, j_rest = shaped_rest(model, betas)
    rot = local_rotations(model, global_orient, body_pose).reshape(-1, model.num_joints, 3, 3)
    tr = jnp.broadcast_to(transl, (*batch, 3)).reshape(-1, 3)
    verts, joints = jax.vmap(lambda r, t: lbs(model, r, t, v_shaped, j_rest))(rot, tr)
    nrm = jax.vmap(lambda v: vertex_normals(v, model.faces))(verts) if normals else None
    unflat = lambda x: None if x is None else x.reshape(*batch, *x.shape[1:])  # noqa: E731
    return BodyOutput(unflat(verts), unflat(nrm), unflat(joints[:, :NUM_JOINTS]))
