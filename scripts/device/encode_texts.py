"""Fill a dataset's text caches (pooled embeddings and token states) for its train and val
texts in one pass, so that training never encodes in its step loop. It goes through the ADM
task's own text path, so the caches are the ones training reads.

    python scripts/device/encode_texts.py DATA_DIR [TEXT_TOKENS]   # default 24, as shipped
"""
import sys
import time
from pathlib import Path

import numpy as np

from jaxmotion.config import load_config
from jaxmotion.train.tasks import get_task

root = Path(sys.argv[1])
tokens = int(sys.argv[2]) if len(sys.argv) > 2 else 24
texts = set()
for split in ("train", "val"):
    for f in sorted((root / "samples" / split).glob("*.npz")):
        with np.load(f) as d:
            texts.add(str(d["text"]))
texts = sorted(texts)
t0 = time.time()
cfg = load_config("configs/adm.py", [f"data_dir={root}", f"model.text_tokens={tokens}"])
task = get_task(cfg)
for lo in range(0, len(texts), 4096):
    task.prepare(cfg, {"text": texts[lo:lo + 4096]})  # the task's text path fills both caches
print(f"encoded {len(texts)} texts in {time.time() - t0:.1f} s", flush=True)
