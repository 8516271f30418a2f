"""The text-to-motion protocol with a floor: HumanML3D, the affordance paper's Table 1.

``jaxmotion eval --protocol text`` runs it on a folder written by ``jaxmotion data convert
--from humanml3d`` (every sample on the one floor scene, no target object). The models sample
each test caption at its clip's length on a floor crop; there is no target, so the goal
distance, contact, non-collision, grounding and action columns do not apply and are left out.
The table has the Table-1 columns on the text–motion evaluator's features (Guo et al. 2022,
:func:`jaxmotion.eval.evaluator.text_motion_scores`): R-precision top 1/2/3, FID, MultiModal
distance, Diversity and MultiModality, with the dataset motions' own row ("Real") as the
reference, and a second table of plausibility measures (teleports, speeds, jerk, floor
penetration, foot skating) at the data's frame rate.

Differences from the paper's evaluation (see ``docs/humanml3d.md``): the evaluator reads
joints and a MiniLM sentence embedding (not the 263-d features and GloVe words of Guo et al.),
so the numbers are comparable with each other, not with the paper's.
"""

from __future__ import annotations

import math
from pathlib import Path

from jaxmotion.data.format import DatasetError, load_manifest

__all__ = ["NOT_APPLICABLE", "TABLE1", "check_text_data", "format_table1", "mean_ci_cell"]

#: ``(key, header)`` of the Table-1 columns, in the paper's order.
TABLE1 = (("r_precision_top1", "R-prec. top-1 ↑"), ("r_precision_top2", "R-prec. top-2 ↑"),
          ("r_precision_top3", "R-prec. top-3 ↑"), ("fid", "FID ↓"),
          ("multimodal_dist", "MM dist. ↓"), ("diversity", "diversity →"),
          ("multimodality", "multimodality ↑"))
#: Per-case columns of the scene protocols that need a target object or furniture.
NOT_APPLICABLE = ("goal_distance", "contact", "non_collision", "in_furniture")
_PLAUSIBILITY = (("teleport", "teleport (%) ↓", 100, 1),
                 ("pelvis_speed_p50", "pelvis speed p50 (m/s)", 1, 2),
                 ("pelvis_speed_p99", "pelvis speed p99 (m/s) ↓", 1, 2),
                 ("joint_speed_max", "top joint speed (m/s) ↓", 1, 2),
                 ("jerk_mean", "jerk (m/s³) ↓", 1, 1),
                 ("floor_penetration", "floor penetration (cm) ↓", 100, 2),
                 ("skating", "skating (%) ↓", 100, 2), ("apd", "APD ↑", 1, 3))


def check_text_data(data_dir, evaluator=None) -> float:
    """The frame rate of a converted HumanML3D folder ``data_dir``; ValueError when it is
    not one, or when ``evaluator`` (an :class:`~jaxmotion.eval.evaluator.Evaluator`) was
    trained on motions at another frame rate."""
    try:
        manifest = load_manifest(data_dir)
    except DatasetError:
        raise DatasetError(f"{data_dir}: no manifest.json; the text protocol reads a folder "
                           "made by 'jaxmotion data convert --from humanml3d SRC --out DIR'"
                           ) from None
    kind = (manifest.get("convert_settings") or {}).get("kind")
    if kind != "humanml3d":
        raise DatasetError(f"{data_dir}: not converted HumanML3D (manifest kind "
                           f"{manifest.get('kind', '?')!r}); the text protocol reads a folder "
                           "made by 'jaxmotion data convert --from humanml3d SRC --out DIR'")
    fps = float(manifest.get("fps") or manifest["convert_settings"]["fps"])
    trained = None if evaluator is None else evaluator.describe().get("fps")
    if trained is not None and abs(float(trained) - fps) > 1e-6:
        raise ValueError(f"the evaluator was trained on {float(trained):g} fps motions but "
                         f"{Path(data_dir)} holds {fps:g} fps motions; train it on this "
                         "conversion (or one at the same --fps)")
    return fps


def mean_ci_cell(s: dict | None, scale: float = 1.0, digits: int = 3) -> str:
    """``mean ± ci95`` of a summary entry ``{mean, ci95, n}`` (times ``scale``); ``–`` when
    it has no value."""
    if not s or s.get("mean") is None:
        return "–"
    m, h = s["mean"] * scale, (s["ci95"] or 0.0) * scale
    return f"{m:.{digits}f} ± {h:.{digits}f}"


def _number(values: dict, key: str, scale: float = 1.0, digits: int = 3) -> str:
    v = values.get(key)
    return "–" if v is None or math.isnan(v) else f"{v * scale:.{digits}f}"


def format_table1(report: dict) -> str:
    """The report of an ``evaluate(protocol="text")`` run as Markdown: the Table-1 columns
    (the dataset motions' row first) and the plausibility table."""
    st = report["settings"]
    lines = [(f"Split `{st['split']}` of `{st['data_dir']}` (HumanML3D, text to motion on a "
              f"floor, {st.get('fps', 20):g} fps): {st['num_cases']} captions × "
              f"{st['samples']} samples × {st['replications']} replications; mean ± 95 % "
              "interval over replications. Evaluator features: joints and MiniLM sentences "
              "(not Guo et al.'s 263-d features and GloVe words), so compare rows of this "
              "table, not with the paper's numbers."), "",
             "**Text to motion (as the affordance paper's Table 1)**", ""]
    head = ["method", "sampler", *(h for _, h in TABLE1)]
    lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    real = report.get("real", {})
    if real:
        lines.append("| " + " | ".join(["real (dataset motions)", "–"] + [
            "–" if k in ("fid", "multimodality") else _number(real, k) for k, _ in TABLE1])
            + " |")
    for name, m in report["models"].items():
        s = m["summary"]
        lines.append("| " + " | ".join([name, m["sampler"]]
                                       + [mean_ci_cell(s.get(k)) for k, _ in TABLE1]) + " |")
    head = ["method", "sampler", *(h for _, h, _, _ in _PLAUSIBILITY)]
    lines += ["", ("**Plausibility** (a teleport: a joint faster than 9 m/s or the pelvis "
                   "faster than 3 m/s between two frames; APD over each caption's samples)"), "",
              "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    g = report.get("ground_truth")
    if g:
        lines.append("| " + " | ".join(["real (dataset motions)", "–"] + [
            "–" if k == "apd" else _number(g, k, sc, d) for k, _, sc, d in _PLAUSIBILITY])
            + " |")
    for name, m in report["models"].items():
        s = m["summary"]
        lines.append("| " + " | ".join([name, m["sampler"]] + [
            mean_ci_cell(s.get(k), sc, d) for k, _, sc, d in _PLAUSIBILITY]) + " |")
    return "\n".join(lines) + "\n"
