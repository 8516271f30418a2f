"""The bodies a clip shows: K posed meshes per frame, skinned on the host, frame by frame.

:func:`skinning` poses SMPL-X parameters' kinematic chain on the host: per sample the rest mesh
at its betas and, per frame and joint, the affine map of linear blend skinning (the viewer page
ships these and blends on the GPU).

:class:`Bodies` hands the renderer ``[K, V, 3]`` vertices for one frame at a time, either from
arrays the caller posed (``body_forward(...).vertices``) or from SMPL-X parameters, skinned here
in NumPy (:meth:`Bodies.from_smplx`): the same linear blend skinning as
:func:`jaxmotion.body.lbs` (pose correctives included for a user's SMPL-X model), with the
kinematic chain of all frames computed once and the vertices of a frame blended when it is
drawn (:func:`jaxmotion.render.kernels.skin`). No XLA program is compiled (each would cost a
fresh process ~0.5 s) and a long motion never holds all its meshes in memory. Betas other than the model's anchor use its linear shape
space (exact for a user's SMPL-X model; first-order for the mannequin, see
:mod:`jaxmotion.body.model`).

Nothing here calls BLAS: on a machine shared with other work its
threads cost more than they save (a frame took twice as long with them).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from jaxmotion.export.rotations import rotvec_to_matrix

__all__ = ["Bodies", "Skinning", "skinning"]


@dataclasses.dataclass(frozen=True)
class Skinning:
    """K skinned bodies over T frames: per sample its ``models[k]``, ``rest[k] = (vertices
    [V, 3], joints [J, 3])`` at its betas, the local joint rotations ``local [K, T, J, 3, 3]``
    and the linear blend skinning maps ``affine [K, T, J, 3, 4]`` float32: joint j carries a
    rest vertex v to ``affine[..., j, :, :3] @ v + affine[..., j, :, 3]``."""

    models: tuple
    rest: tuple
    local: np.ndarray
    affine: np.ndarray


def skinning(global_orient, body_pose, transl, betas=None, model=None) -> Skinning:
    """The skinning of SMPL-X parameters ``[(K,) T, 3]``, ``[(K,) T, 21, 3]`` (or
    ``[..., 63]``), ``[(K,) T, 3]``, ``betas [(K,) B]`` on ``model``; None: the mannequin
    built at each sample's betas (exact mesh). The kinematic chain of every frame, on the host;
    the joints after the 22 body joints hold the model's ``fixed_pose``."""
    from jaxmotion.body.model import load_mannequin, shaped_rest_host

    go = np.asarray(global_orient, np.float64)
    go = go[None] if go.ndim == 2 else go
    k, t = go.shape[:2]
    bp = np.asarray(body_pose, np.float64).reshape(k, t, 21, 3)
    tr = np.asarray(transl, np.float64).reshape(k, t, 3)
    if go.shape != (k, t, 3):
        raise ValueError(f"global_orient must be [T, 3] or [K, T, 3], got {list(go.shape)}")
    if not all(np.all(np.isfinite(x)) for x in (go, bp, tr)):
        raise ValueError("the SMPL-X parameters have non-finite values")
    if betas is not None:
        betas = np.asarray(betas, np.float64)
        betas = np.broadcast_to(betas if betas.ndim == 2 else betas[None], (k, betas.shape[-1]))
    anchored = model is None  # each sample's own mannequin, exact at its betas
    models = [model] * k if not anchored else [
        load_mannequin(None if betas is None else betas[s]) for s in range(k)]
    parents = models[0].parents
    fixed = np.asarray(models[0].fixed_pose, np.float64)
    num_joints = len(parents)
    rest = [shaped_rest_host(m, None if betas is None or anchored else betas[s])
            for s, m in enumerate(models)]
    aa = np.concatenate([go[:, :, None], bp, np.broadcast_to(
        fixed[22:], (k, t, num_joints - 22, 3))], axis=2)
    local = rotvec_to_matrix(aa)  # [K, T, J, 3, 3]
    # affine [K, T, J, 3, 4] per joint: v ↦ G_j v + (p_j − G_j b_j)
    affine = np.empty((k, t, num_joints, 3, 4))
    for s in range(k):
        _, j_rest = rest[s]
        g = np.empty((t, num_joints, 3, 3))
        p = np.empty((t, num_joints, 3))
        g[:, 0] = local[s, :, 0]
        p[:, 0] = j_rest[0] + tr[s]
        for j in range(1, num_joints):
            q = parents[j]
            g[:, j] = g[:, q] @ local[s, :, j]
            p[:, j] = p[:, q] + g[:, q] @ (j_rest[j] - j_rest[q])
        affine[s, :, :, :, :3] = g
        affine[s, :, :, :, 3] = p - np.einsum("tjab,jb->tja", g, j_rest)
    return Skinning(tuple(models), tuple(rest), local, affine.astype(np.float32))


class Bodies:
    """K posed meshes over T frames sharing ``faces [F, 3]``; :meth:`frame` gives ``[K, V, 3]``."""

    def __init__(self, faces, num_samples: int, num_frames: int, frame_fn):
        self.faces = np.asarray(faces, np.int64)
        self.num_samples, self.num_frames = int(num_samples), int(num_frames)
        self._frame_fn = frame_fn

    def frame(self, f: int) -> np.ndarray:
        """Vertices of every sample at frame ``f``: ``[K, V, 3]`` float32, world, metres."""
        return self._frame_fn(int(f))

    @staticmethod
    def from_vertices(vertices, faces) -> Bodies:
        """Posed vertices ``[(K,) T, V, 3]`` and their triangles ``faces [F, 3]``."""
        v = np.asarray(vertices)
        v = v[None] if v.ndim == 3 else v
        if v.ndim != 4 or v.shape[-1] != 3:
            raise ValueError(f"vertices must be [T, V, 3] or [K, T, V, 3], got {list(v.shape)}")
        f = np.asarray(faces)
        if f.ndim != 2 or f.shape[1] != 3 or (f.size and (f.min() < 0 or f.max() >= v.shape[2])):
            raise ValueError(f"faces must be [F, 3] indices into the {v.shape[2]} vertices")
        if not np.all(np.isfinite(v)):
            raise ValueError("vertices has non-finite values (NaN or inf)")
        return Bodies(f, v.shape[0], v.shape[1], lambda i: np.asarray(v[:, i], np.float32))

    @staticmethod
    def from_smplx(global_orient, body_pose, transl, betas=None, model=None) -> Bodies:
        """SMPL-X parameters ``[(K,) T, 3]``, ``[(K,) T, 21, 3]`` (or ``[..., 63]``),
        ``[(K,) T, 3]``, ``betas [(K,) B]`` posed on ``model``; None: the mannequin built at
        each sample's betas (exact mesh, as in ``motion.glb``)."""
        skin = skinning(global_orient, body_pose, transl, betas, model)
        model, rest, local = skin.models[0], skin.rest, skin.local
        k = len(rest)
        affine = skin.affine.reshape(*skin.affine.shape[:3], 12)
        influence, weight, count = _influences(np.asarray(model.weights, np.float32))
        posedirs = np.asarray(model.posedirs, np.float64)
        eye = np.eye(3)
        rest32 = [np.ascontiguousarray(r[0], np.float32) for r in rest]

        def frame(i: int) -> np.ndarray:
            from jaxmotion.render import kernels

            out = np.empty((k, len(influence), 3), np.float32)
            for s in range(k):
                v = rest32[s]
                if posedirs.shape[-1]:
                    feat = (local[s, i, 1:22] - eye).reshape(-1)[: posedirs.shape[-1]]
                    v = (rest[s][0] + posedirs @ feat).astype(np.float32)
                kernels.skin(v, affine[s, i], influence, weight, count, out[s])
            return out

        return Bodies(np.asarray(model.faces, np.int64), k, local.shape[1], frame)


def _influences(weights: np.ndarray, most: int = 8):
    """Each vertex's strongest joints ``[V, C]`` int64 and their weights ``[V, C]`` float32,
    strongest first, and how many it has, ``count [V]`` (C ≤ ``most``; weights renormalised
    when cut). Most of the mannequin's vertices follow one joint: their map is taken as it is
    (:func:`jaxmotion.render.kernels.skin`)."""
    count = np.minimum((weights > 0).sum(1), most)
    c = max(1, int(count.max()))
    idx = np.ascontiguousarray(np.argsort(-weights, axis=1, kind="stable")[:, :c])
    ww = np.take_along_axis(weights, idx, axis=1).astype(np.float32)
    ww /= ww.sum(1, keepdims=True)
    return idx.astype(np.int64), np.ascontiguousarray(ww), count.astype(np.int64)
