"""Cold and warm end-to-end time of `jaxmotion generate` (the README's main job).

Runs the command in fresh Python processes, as a user does:

- **cold**: an empty persistent compilation cache (first run after install);
- **warm**: the same cache again (every later run); the target is ≤ 5 s on a 2-core CPU
  for one 4-second motion at the default sampler.

Prints wall-clock seconds of the whole process (import, load, sampling, body fit, writing
every output) and the per-stage split reported by the command itself.

With ``--new-texts`` warm runs ask for sentences never seen before (the text encoder runs; two
name no object of the demo room, so an object to walk to is drawn, one of them with a verb
only the sentence encoder's similarity reads; one names a class the room has two of, so the
free floor chooses), in two rounds of the same kinds: the first round may trace a program for
a new shape (once per cache), the second is what a user typing new sentences gets from then
on. ``--grounding adm`` times the affordance model's choice instead for those kinds.

    python benchmarks/generate.py [--runs 3] [--steps 20] [--video mp4|gif|none] [--consistency S]
        [--adm-candidates C] [--adm-steps N] [--motion-candidates M] [--new-texts]
        [--grounding auto|adm]
        [--pipeline auto|affordance|object-centric] [--object-checkpoints DIR | TRAJ COMP]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time

#: Sentences for --new-texts, in two rounds of the same kinds (the first of a kind may trace a
#: program for its shape: once per cache): the target found by class, a class the room has two
#: of, no object of the room named with a known verb, the same with a verb the word lists do
#: not know (the sentence encoder's similarity reads it), a target told by class.
NEW_TEXTS = (
    ("take a seat on the chair at the table", "sit down on the stool", "wander around for a bit",
     "jump around for a bit", "go and stand by the table"),
    ("have a seat on the chair", "walk over to the stool", "stroll around for a while",
     "dance around the room", "walk up to the table"),
)


def run_once(cache: str, out: str, args, text: str | None = None) -> tuple[float, dict]:
    env = {**os.environ, "JAXMOTION_CACHE": cache, "JAX_PLATFORMS": "cpu"}
    cmd = [sys.executable, "-m", "jaxmotion", "generate", "--scene", "demo", "--out", out,
           "--steps", str(args.steps), "--video", args.video, "--samples", str(args.samples)]
    if text is not None:
        cmd += ["--text", text]
    if args.checkpoints:
        cmd += ["--checkpoints", *args.checkpoints]
    if args.consistency is not None:
        cmd += ["--consistency", str(args.consistency)]
    if args.adm_candidates is not None:
        cmd += ["--adm-candidates", str(args.adm_candidates)]
    if args.motion_candidates is not None:
        cmd += ["--motion-candidates", str(args.motion_candidates)]
    if args.adm_steps is not None:
        cmd += ["--adm-steps", str(args.adm_steps)]
    if args.pipeline != "auto":
        cmd += ["--pipeline", args.pipeline]
    if args.grounding != "auto":
        cmd += ["--grounding", args.grounding]
    if args.object_checkpoints:
        cmd += ["--object-checkpoints", *args.object_checkpoints]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        sys.exit(f"generate failed:\n{proc.stderr}")
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    return wall, summary["timings_s"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3, help="warm runs (default 3)")
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--samples", type=int, default=1)
    ap.add_argument("--video", default="mp4", choices=("gif", "mp4", "none"),
                    help="the video written (default: mp4, as jaxmotion generate)")
    ap.add_argument("--checkpoints", nargs="+", default=None)
    ap.add_argument("--pipeline", default="auto", choices=("auto", "affordance", "object-centric"),
                    help="which pipeline generate runs (default: generate's own, auto; time two "
                    "in one session to compare)")
    ap.add_argument("--grounding", default="auto", choices=("auto", "adm"),
                    help="how several candidates (or none named) are chosen among (default: "
                    "generate's own, auto: the room's free floor; adm: the ADM's map)")
    ap.add_argument("--object-checkpoints", nargs="+", default=None,
                    help="the object-centric models (folder, or trajectory and completion runs)")
    ap.add_argument("--consistency", type=float, default=None,
                    help="consistency-guidance strength (default: the command's; 0 = off)")
    ap.add_argument("--adm-candidates", type=int, default=None,
                    help="ADM maps per sample for a known target (default: the command's)")
    ap.add_argument("--adm-steps", type=int, default=None,
                    help="DDIM steps of the ADM stage (default: the command's)")
    ap.add_argument("--motion-candidates", type=int, default=None,
                    help="motions per map for a known target (default: the command's)")
    ap.add_argument("--new-texts", action="store_true",
                    help="also time warm runs of sentences never seen before (up to 10)")
    args = ap.parse_args()
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, "
          f"python {platform.python_version()}")
    print(f"jaxmotion generate --scene demo --steps {args.steps} --samples {args.samples} "
          f"--video {args.video}"
          + ("" if args.consistency is None else f" --consistency {args.consistency:g}")
          + ("" if args.adm_candidates is None else f" --adm-candidates {args.adm_candidates}")
          + ("" if args.adm_steps is None else f" --adm-steps {args.adm_steps}")
          + ("" if args.motion_candidates is None
             else f" --motion-candidates {args.motion_candidates}")
          + ("" if args.grounding == "auto" else f" --grounding {args.grounding}"))
    with tempfile.TemporaryDirectory() as tmp:
        cache, out = os.path.join(tmp, "cache"), os.path.join(tmp, "out")
        cold, cold_st = run_once(cache, out, args)
        warm = [run_once(cache, out, args) for _ in range(args.runs)]
        first = [run_once(cache, out, args, t) for t in NEW_TEXTS[0]] if args.new_texts else []
        new = [run_once(cache, out, args, t) for t in NEW_TEXTS[1]] if args.new_texts else []
    stages = sorted(set(cold_st) | {k for _, st in warm for k in st})
    print(f"{'run':<8}{'wall s':>8}  " + "".join(f"{s:>9}" for s in stages))
    print(f"{'cold':<8}{cold:8.2f}  " + "".join(f"{cold_st.get(s, 0):9.2f}" for s in stages))
    for i, (w, st) in enumerate(warm):
        print(f"{f'warm {i + 1}':<8}{w:8.2f}  " + "".join(f"{st.get(s, 0):9.2f}" for s in stages))
    for label, rows, texts in (("first", first, NEW_TEXTS[0]), ("new", new, NEW_TEXTS[1])):
        for i, (w, st) in enumerate(rows):
            print(f"{f'{label} {i + 1}':<8}{w:8.2f}  "
                  + "".join(f"{st.get(s, 0):9.2f}" for s in stages) + f"   {texts[i]!r}")
    med = statistics.median(w for w, _ in warm)
    print(f"warm median {med:.2f} s (target ≤ 5 s: {'met' if med <= 5.0 else 'NOT met'}); "
          f"cold / warm = {cold / med:.1f}x")
    if new:
        med_new, worst = statistics.median(w for w, _ in new), max(w for w, _ in new)
        print(f"new sentences (their kind seen before), warm: median {med_new:.2f} s, slowest "
              f"{worst:.2f} s (target ≤ 5 s: {'met' if worst <= 5.0 else 'NOT met'}); "
              f"{med_new - med:+.2f} s over the repeated sentence")


if __name__ == "__main__":
    main()
