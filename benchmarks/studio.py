"""The studio's warm process: how long a click, a new sentence and a story take.

    python benchmarks/studio.py [--rounds 3] [--json OUT]

Targets (2 cores): a clip for a new sentence or a click ≤ 1.5 s from request to motion (the
files are written afterwards, on the studio's second thread), a 3-step story ≤ 6 s, the first
request after start ≤ the cold ``generate``.

In one process, through the HTTP API (FastAPI's in-process client, so the figures include
the request, the queue and the JSON with the joints, not a network):

1. **first request**: a studio started on the demo room with an empty compilation cache
   (``JAXMOTION_CACHE`` pointed at a new folder), no warm-up; a click on the chair, timed
   from the request to the answer of ``?wait=true``. The baseline, measured in the same run:
   the cold command-line ``jaxmotion generate`` in a fresh process on that empty cache;
2. **warm** (after :meth:`Studio.warm_up`, which a started studio runs before the first
   click, and one story), after each previous job's files are written (the user watches the result
   before the next click): clicks on each seat, new sentences (each sentence new to the
   process: the text encoder runs), a floor point, and a 3-step story (walk to a point,
   walk to the table, sit on the chair), ``--rounds`` times each with new seeds.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--json", default=None, help="write the figures here")
    ap.add_argument("--no-cold", action="store_true", help="skip the cold CLI baseline")
    args = ap.parse_args(argv)
    cache = tempfile.mkdtemp(prefix="jm-studio-bench-")
    os.environ["JAXMOTION_CACHE"] = cache
    out: dict = {}
    if not args.no_cold:
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "jaxmotion", "generate", "--scene", "demo",
                            "--text", "sit on the chair", "--out", f"{tmp}/out", "--video",
                            "none"], check=True, capture_output=True,
                           env={**os.environ, "JAXMOTION_CACHE": f"{tmp}/cache"})
            out["cold_cli_generate_s"] = round(time.perf_counter() - t0, 2)
            print(f"cold CLI generate (fresh process, empty cache): "
                  f"{out['cold_cli_generate_s']:.2f} s", flush=True)

    from fastapi.testclient import TestClient

    from jaxmotion.studio import Studio, create_app

    t0 = time.perf_counter()
    studio = Studio(Path(cache) / "studio", "demo", video="mp4", warm=False)
    client = TestClient(create_app(studio))
    out["studio_start_s"] = round(time.perf_counter() - t0, 2)
    objects = {o["category"]: o["id"] for o in client.get("/api/scene").json()["objects"]}

    def timed(body):
        t = time.perf_counter()
        r = client.post("/api/generate?wait=true", json=body)
        dt = time.perf_counter() - t
        if r.status_code != 200:
            raise SystemExit(f"{body}: {r.json()}")
        studio.idle(600)  # the files, before the next request
        return dt

    out["first_request_s"] = round(timed({"object_id": objects["chair"]}), 2)
    print(f"studio start {out['studio_start_s']:.2f} s; first request (a click, cold): "
          f"{out['first_request_s']:.2f} s", flush=True)
    studio.warm_up()  # what a started studio does on its own before the first click
    timed({"plan": [{"action": "walk", "point": [2.0, 3.0]},
                    {"action": "sit", "object": objects["chair"]}]})  # the story programs
    sentences = ["have a seat on the stool", "go and stand by the fridge",
                 "walk over to the armchair", "sit down on the chair by the table",
                 "take a seat on the armchair", "wander to the window", "stroll to the door",
                 "sit on the other stool", "head to the cabinet"]
    kinds = {"click": [], "sentence": [], "point": [], "story3": []}
    seats = [objects[c] for c in ("chair", "armchair", "stool") if c in objects]
    for r in range(args.rounds):
        for oid in seats:
            kinds["click"].append(timed({"object_id": oid, "seed": 10 + r}))
        for text in sentences[3 * r: 3 * r + 3]:
            kinds["sentence"].append(timed({"text": text, "seed": 20 + r}))
        kinds["point"].append(timed({"point": [1.2 + 0.3 * r, 3.5], "seed": 30 + r}))
        kinds["story3"].append(timed({"plan": [
            {"action": "walk", "point": [1.0 + 0.4 * r, 4.0]},
            {"action": "walk", "object": objects["table"]},
            {"action": "sit", "object": objects["chair"]}], "seed": 40 + r}))
    for kind, times in kinds.items():
        out[f"{kind}_median_s"] = round(statistics.median(times), 2)
        out[f"{kind}_max_s"] = round(max(times), 2)
        print(f"{kind:9s} median {statistics.median(times):.2f} s, slowest {max(times):.2f} s "
              f"({len(times)} runs)", flush=True)
    if "cold_cli_generate_s" in out:
        print(f"first request / cold CLI generate: "
              f"{out['first_request_s'] / out['cold_cli_generate_s']:.2f}")
    studio.close()
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
