"""scripts/device/minilm_vocab.py: the pruned sentence encoder that travels to a GPU machine
covers every instruction the generator writes, in either phrasing, and says so when a
dataset's text is not covered."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "device" / "minilm_vocab.py"


def _dataset(folder: Path, texts) -> Path:
    out = folder / "samples" / "train"
    out.mkdir(parents=True)
    for i, t in enumerate(texts):
        np.savez(out / f"{i:05d}.npz", text=np.array(t))
    return folder


def _run(*args):
    return subprocess.run([sys.executable, str(SCRIPT), *map(str, args)], capture_output=True,
                          text=True, check=False)


@pytest.fixture(scope="module")
def pruned(tmp_path_factory):
    from jaxmotion.text.minilm import minilm_dir

    folder = tmp_path_factory.mktemp("minilm") / "model"
    shutil.copytree(minilm_dir(), folder)
    done = _run("prune", folder)  # no dataset: the generator's words alone
    assert done.returncode == 0, done.stderr
    return folder


def test_rich_instructions_are_covered_and_encode_as_with_the_full_model(pruned, tmp_path):
    from jaxmotion.scene.instructions import sample_task
    from jaxmotion.scene.rooms import sample_room
    from jaxmotion.text.minilm import load_minilm

    texts = set()
    for r in range(12):
        room = sample_room(np.random.default_rng(4000 + r))
        for k in range(12):
            for phrasing in ("default", "rich"):
                texts.add(sample_task(room, np.random.default_rng([r, k]), phrasing=phrasing)[0])
    data = _dataset(tmp_path / "data", sorted(texts))
    ok = _run("check", pruned, data)
    assert ok.returncode == 0 and f"all {len(texts)} texts" in ok.stdout, ok.stderr
    restored = tmp_path / "restored"
    assert _run("restore", pruned, restored).returncode == 0
    some = sorted(texts)[::17][:6]
    np.testing.assert_array_equal(load_minilm(restored)(some), load_minilm()(some))


def test_a_text_the_pruned_model_lacks_is_named(pruned, tmp_path):
    data = _dataset(tmp_path / "odd", ["sit on the chair", "perch on the zyzzyva"])
    bad = _run("check", pruned, data)
    assert bad.returncode == 1
    assert "zyzzyva" in bad.stderr and "prepare.sh" in bad.stderr
