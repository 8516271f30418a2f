"""Fill a dataset's text caches (pooled embeddings and token states) for its train and val
texts in one pass, so that training never encodes in its step loop.

    python scripts/device/encode_texts.py DATA_DIR
"""
import sys
import time
from pathlib import Path

import numpy as np

from jaxmotion.text import EmbeddingCache, TokenCache, load_text_encoder

root = Path(sys.argv[1])
texts = set()
for split in ("train", "val"):
    for f in sorted((root / "samples" / split).glob("*.npz")):
        with np.load(f) as d:
            texts.add(str(d["text"]))
texts = sorted(texts)
t0 = time.time()
enc = load_text_encoder("minilm")
emb = EmbeddingCache(root / ".cache" / "text")
tok = TokenCache(root / ".cache" / "text-tokens")
for lo in range(0, len(texts), 4096):
    emb.encode(enc, texts[lo:lo + 4096])
    tok.states(enc, texts[lo:lo + 4096])
print(f"encoded {len(texts)} texts in {time.time() - t0:.1f} s", flush=True)
