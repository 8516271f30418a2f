"""Text–motion metrics of Guo et al. 2022 (HumanML3D), without the trained evaluator.

These take features already produced by a text–motion evaluator (its motion
encoder and text encoder, trained contrastively) and reproduce the protocol's
arithmetic exactly. They run on the host in float64 numpy (the matrix square
root needs :func:`scipy.linalg.sqrtm`); random pair choices come from an
explicit :class:`numpy.random.Generator` (or an int seed).

- FID: Fréchet distance between Gaussians fitted to two feature sets,
  ``|μ_a − μ_b|² + tr(Σ_a + Σ_b − 2 (Σ_a Σ_b)^{1/2})``.
- R-precision: texts and motions in pools of 32 pairs; for each text rank the
  pool's motions by Euclidean distance; top-k = fraction of texts whose own
  motion is among the k nearest, k = 1, 2, 3.
- MultiModal distance: mean ``|t_i − m_i|`` over matched pairs.
- Diversity: mean ``|f_a − f_b|`` over 300 random pairs of generated motions.
- MultiModality: per text, mean ``|f_{c,a} − f_{c,b}|`` over 10 random pairs of its
  generated samples, averaged over texts.
"""

from __future__ import annotations

import warnings

import numpy as np

__all__ = [
    "diversity",
    "euclidean_distance_matrix",
    "fid",
    "frechet_distance",
    "multimodal_distance",
    "multimodality",
    "r_precision",
]


def _rng(rng) -> np.random.Generator:
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None:
        return np.random.default_rng(0)
    return np.random.default_rng(rng)


def _features(x, name: str, ndim: int = 2) -> np.ndarray:
    x = np.asarray(x, np.float64)
    if x.ndim != ndim:
        raise ValueError(f"{name} must have {ndim} axes, got shape {x.shape}")
    if x.shape[0] == 0:
        raise ValueError(f"{name} is empty")
    return x


def euclidean_distance_matrix(a, b) -> np.ndarray:
    """``[N, D], [M, D] -> [N, M]`` Euclidean distances (exact differences, float64)."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    return np.sqrt(np.sum((a[:, None, :] - b[None, :, :]) ** 2, axis=-1))


def frechet_distance(mu1, sigma1, mu2, sigma2, eps: float = 1e-6) -> float:
    """Fréchet distance between ``N(μ1, Σ1)`` and ``N(μ2, Σ2)``.

    ``d² = |μ1 − μ2|² + tr(Σ1) + tr(Σ2) − 2 tr((Σ1 Σ2)^{1/2})``. As in the
    reference code, a non-finite square root (or one scipy calls inaccurate: the product of
    singular covariances, fewer samples than dimensions) is retried with ``eps·I`` added to
    both covariances, and a complex result with negligible imaginary part is
    made real (``ValueError`` otherwise).
    """
    mu1, mu2 = np.atleast_1d(mu1).astype(np.float64), np.atleast_1d(mu2).astype(np.float64)
    s1, s2 = np.atleast_2d(sigma1).astype(np.float64), np.atleast_2d(sigma2).astype(np.float64)
    if mu1.shape != mu2.shape or s1.shape != s2.shape or s1.shape != (mu1.size, mu1.size):
        raise ValueError("means [D] and covariances [D, D] must agree in D")
    from scipy import linalg  # here: the import costs every generate ~0.1 s

    diff = mu1 - mu2
    with warnings.catch_warnings(record=True) as caught:
        # a covariance of fewer samples than dimensions is singular: scipy warns that its
        # square root may be inaccurate; then retry with the offset, as for a non-finite one
        warnings.simplefilter("always", linalg.LinAlgWarning)
        covmean = linalg.sqrtm(s1 @ s2)
    if not np.isfinite(covmean).all() or any(issubclass(w.category, linalg.LinAlgWarning)
                                             for w in caught):
        offset = np.eye(s1.shape[0]) * eps
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", linalg.LinAlgWarning)
            covmean = linalg.sqrtm((s1 + offset) @ (s2 + offset))
    if np.iscomplexobj(covmean):
        if not np.allclose(np.diagonal(covmean).imag, 0, atol=1e-3):
            raise ValueError(f"imaginary component {np.max(np.abs(covmean.imag))} in sqrtm")
        covmean = covmean.real
    return float(diff @ diff + np.trace(s1) + np.trace(s2) - 2.0 * np.trace(covmean))


def fid(features_a, features_b) -> float:
    """FID between two feature sets ``[N, D]`` and ``[M, D]`` (N, M ≥ 2).

    Mean and covariance (unbiased, ``np.cov``) of each set, then
    :func:`frechet_distance`. Units: squared feature units.
    """
    a = _features(features_a, "features_a")
    b = _features(features_b, "features_b")
    if a.shape[1] != b.shape[1]:
        raise ValueError(f"feature widths differ: {a.shape[1]} vs {b.shape[1]}")
    if a.shape[0] < 2 or b.shape[0] < 2:
        raise ValueError("FID needs at least 2 samples per set for a covariance")
    return frechet_distance(a.mean(0), np.cov(a, rowvar=False), b.mean(0), np.cov(b, rowvar=False))


def r_precision(text_emb, motion_emb, top_k: int = 3, pool: int = 32, rng=None) -> np.ndarray:
    """R-precision: ``[B, D], [B, D] -> [top_k]`` top-1..top_k retrieval accuracy in [0, 1].

    Pairs ``(text_emb[i], motion_emb[i])`` match. The B pairs are cut into
    ``B // pool`` consecutive pools of ``pool`` (32) pairs — an incomplete last
    pool is dropped, as the reference data loader does (``drop_last``); pass
    ``rng`` to shuffle the pairs first. In each pool, text i ranks the pool's
    motions by Euclidean distance (ties: lower index first); entry k−1 of the
    result is the fraction of texts whose own motion is among the k nearest.
    """
    t = _features(text_emb, "text_emb")
    m = _features(motion_emb, "motion_emb")
    if t.shape != m.shape:
        raise ValueError(f"text_emb {t.shape} and motion_emb {m.shape} must match")
    if top_k < 1 or top_k > pool:
        raise ValueError(f"need 1 <= top_k <= pool, got top_k={top_k}, pool={pool}")
    n_pools = t.shape[0] // pool
    if n_pools == 0:
        raise ValueError(f"need at least one full pool of {pool} pairs, got {t.shape[0]}")
    if rng is not None:
        perm = _rng(rng).permutation(t.shape[0])
        t, m = t[perm], m[perm]
    hits = np.zeros(top_k)
    for p in range(n_pools):
        sl = slice(p * pool, (p + 1) * pool)
        order = np.argsort(euclidean_distance_matrix(t[sl], m[sl]), axis=1, kind="stable")
        rank = np.argmax(order == np.arange(pool)[:, None], axis=1)  # 0 = nearest
        hits += np.array([(rank < k).sum() for k in range(1, top_k + 1)])
    return hits / (n_pools * pool)


def multimodal_distance(text_emb, motion_emb) -> float:
    """MultiModal distance: ``mean_i |text_emb[i] − motion_emb[i]|``, ``[B, D] x2 -> ()``."""
    t = _features(text_emb, "text_emb")
    m = _features(motion_emb, "motion_emb")
    if t.shape != m.shape:
        raise ValueError(f"text_emb {t.shape} and motion_emb {m.shape} must match")
    return float(np.mean(np.linalg.norm(t - m, axis=1)))


def diversity(features, num_pairs: int = 300, rng=None) -> float:
    """Diversity: ``mean_p |f[a_p] − f[b_p]|`` over ``num_pairs`` random pairs, ``[N, D] -> ()``.

    As in Guo et al.: ``a`` and ``b`` are each ``num_pairs`` indices drawn without
    replacement (independently, so ``a_p = b_p`` may happen and adds 0). Needs
    N ≥ num_pairs. ``rng``: numpy Generator or int seed (None = seed 0).
    """
    f = _features(features, "features")
    if f.shape[0] < num_pairs:
        raise ValueError(f"diversity needs at least num_pairs={num_pairs} samples, got {len(f)}")
    g = _rng(rng)
    a = g.choice(f.shape[0], num_pairs, replace=False)
    b = g.choice(f.shape[0], num_pairs, replace=False)
    return float(np.mean(np.linalg.norm(f[a] - f[b], axis=1)))


def multimodality(features, num_pairs: int = 10, rng=None) -> float:
    """MultiModality: ``mean_c mean_p |f[c, a_p] − f[c, b_p]|``, ``[C, R, D] -> ()``.

    ``C`` texts (cases) with ``R`` generated samples each (30 in the protocol).
    As in Guo et al., one draw of ``a`` and ``b`` (each ``num_pairs`` indices
    without replacement, so ``a_p = b_p`` may happen) is shared by all cases.
    Needs R ≥ num_pairs. ``rng``: numpy Generator or int seed (None = seed 0).
    """
    f = _features(features, "features", ndim=3)
    if f.shape[1] < num_pairs:
        raise ValueError(
            f"multimodality needs at least num_pairs={num_pairs} samples per case, got {f.shape[1]}"
        )
    g = _rng(rng)
    a = g.choice(f.shape[1], num_pairs, replace=False)
    b = g.choice(f.shape[1], num_pairs, replace=False)
    return float(np.mean(np.linalg.norm(f[:, a] - f[:, b], axis=2)))
