"""The persistent compilation cache: per-host executables, and a switch to turn it off."""

import os

import jax

from jaxmotion import _jax_setup as S


def test_host_key_is_stable_and_short():
    assert S.host_key() == S.host_key()
    assert len(S.host_key()) == 12 and all(c in "0123456789abcdef" for c in S.host_key())


def test_executables_are_kept_per_host(tmp_path, monkeypatch):
    monkeypatch.setenv("JAXMOTION_CACHE", str(tmp_path / "c"))
    monkeypatch.setenv("JAXMOTION_XLA_CACHE", "off")  # the suite's XLA cache left as it is
    root = S.enable_compilation_cache()
    assert root == tmp_path / "c"
    assert (root / f"executables-{S.host_key()}").is_dir()


def test_cache_off_writes_nothing_to_the_named_place(tmp_path, monkeypatch):
    before = jax.config.jax_compilation_cache_dir
    monkeypatch.setenv("JAXMOTION_CACHE", "off")
    root = S.enable_compilation_cache()
    assert root.is_dir() and os.access(root, os.W_OK)
    assert jax.config.jax_compilation_cache_dir == before  # XLA's cache left as it was
    assert S.enable_compilation_cache() == root  # one scratch folder per process


def test_xla_cache_off_keeps_jaxmotions_own_root(tmp_path, monkeypatch):
    before = jax.config.jax_compilation_cache_dir
    monkeypatch.setenv("JAXMOTION_CACHE", str(tmp_path / "own"))
    monkeypatch.setenv("JAXMOTION_XLA_CACHE", "off")
    assert S.enable_compilation_cache() == tmp_path / "own"
    assert jax.config.jax_compilation_cache_dir == before


def test_seed_key_data_is_jaxs_key():
    import jax
    import numpy as np

    from jaxmotion._jax_setup import seed_key_data

    for seed in (0, 1, 3, 12345, 2**31 - 1, 2**31, 2**40):
        want = np.asarray(jax.random.key_data(jax.random.key(seed)))
        got = seed_key_data(seed)
        assert got.dtype == want.dtype and np.array_equal(got, want), seed
