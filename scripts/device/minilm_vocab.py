"""Shrink / restore the float16 MiniLM that travels to a device machine (64 MiB limit).

``prune DIR DATA_DIR``: keep only the rows of the word-embedding matrix (30,522 x 384, half of
the weights) that the tokenizer uses for the texts of DATA_DIR (every split), stored as
``vocab_rows.npz`` (ids, rows) beside a model.safetensors without that matrix. For those texts
the encoder gives exactly what the full float16 model gives; any other word would read a zero
row, so the device only encodes the dataset's own texts (scripts/device/encode_texts.py).

``restore DIR OUT``: write the full model folder OUT (the pruned rows back in place, zeros
elsewhere), to point JAXMOTION_MINILM_DIR at.
"""
import shutil
import sys
from pathlib import Path

import numpy as np
from safetensors.numpy import load_file, save_file

KEY = "embeddings.word_embeddings.weight"


def prune(folder: Path, data: Path) -> None:
    from tokenizers import Tokenizer

    tok = Tokenizer.from_file(str(folder / "tokenizer.json"))
    texts = set()
    for f in sorted((data / "samples").glob("*/*.npz")):
        with np.load(f) as d:
            texts.add(str(d["text"]))
    ids = set()
    for enc in tok.encode_batch(sorted(texts)):
        ids.update(enc.ids)
    ids = np.asarray(sorted(ids), np.int64)
    tensors = load_file(str(folder / "model.safetensors"))
    emb = tensors.pop(KEY)
    np.savez(folder / "vocab_rows.npz", ids=ids, rows=emb[ids], shape=np.asarray(emb.shape))
    save_file(tensors, str(folder / "model.safetensors"))
    print(f"{len(texts)} texts use {len(ids)} of {emb.shape[0]} word pieces")


def restore(folder: Path, out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    for f in folder.iterdir():
        if f.name not in ("model.safetensors", "vocab_rows.npz"):
            shutil.copy(f, out / f.name)
    tensors = load_file(str(folder / "model.safetensors"))
    with np.load(folder / "vocab_rows.npz") as z:
        full = np.zeros(tuple(z["shape"]), z["rows"].dtype)
        full[z["ids"]] = z["rows"]
    save_file({**tensors, KEY: full}, str(out / "model.safetensors"))


if __name__ == "__main__":
    if len(sys.argv) != 4 or sys.argv[1] not in ("prune", "restore"):
        sys.exit("usage: minilm_vocab.py prune DIR DATA_DIR | restore DIR OUT")
    (prune if sys.argv[1] == "prune" else restore)(Path(sys.argv[2]), Path(sys.argv[3]))
