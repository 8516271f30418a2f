"""Shared test setup: small, fast, deterministic."""

import os

# Keep XLA from grabbing every core for thread pools in tiny tests.
os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false")

from hypothesis import HealthCheck, settings  # noqa: E402

settings.register_profile(
    "jaxmotion",
    max_examples=25,
    deadline=None,  # jit compilation makes first examples slow
    suppress_health_check=[HealthCheck.too_slow],
    derandomize=True,
)
settings.load_profile("jaxmotion")
