"""Shrink / restore / check the float16 MiniLM that travels to a device machine (64 MiB limit).

``prune DIR [DATA_DIR]``: keep only the rows of the word-embedding matrix (30,522 x 384, half
of the weights) that the tokenizer can need for the synthetic world's instructions, stored as
``vocab_rows.npz`` (ids, rows) beside a model.safetensors without that matrix. The rows kept
are those of (a) every word the instruction generator can write, in either phrasing (the
string constants of ``jaxmotion/scene/*.py``: the templates, the rich phrasing's word lists,
the object classes and their words), and (b) the texts of DATA_DIR (every split) when given,
for a dataset from elsewhere. A word piece depends on its word alone (BERT splits the text on
spaces and punctuation first), so any text made of those words encodes exactly as with the
full float16 model; any other word would read a zero row.

``check DIR DATA_DIR``: exit 1, naming the text and its word, if a text of DATA_DIR uses a
word piece the pruned model lacks (the device calls it before it encodes a dataset it built).

``restore DIR OUT``: write the full model folder OUT (the pruned rows back in place, zeros
elsewhere), to point JAXMOTION_MINILM_DIR at.
"""
import ast
import shutil
import sys
from pathlib import Path

import numpy as np
from safetensors.numpy import load_file, save_file

KEY = "embeddings.word_embeddings.weight"
GENERATOR = Path(__file__).resolve().parents[2] / "jaxmotion" / "scene"


def generator_strings() -> set[str]:
    """Every string constant of the synthetic world's modules (the instruction generator's
    words among them), placeholders such as ``{a}`` blanked."""
    out = set()
    for f in sorted(GENERATOR.glob("*.py")):
        for node in ast.walk(ast.parse(f.read_text(), str(f))):
            if isinstance(node, ast.Constant) and isinstance(node.value, str):
                out.add(node.value.replace("{", " ").replace("}", " ").replace("_", " "))
    out.update(str(n) for n in range(200))  # object ids ("chair 3")
    return out


def dataset_texts(data: Path) -> set[str]:
    texts = set()
    for f in sorted((data / "samples").glob("*/*.npz")):
        with np.load(f) as d:
            texts.add(str(d["text"]))
    return texts


def _tokenizer(folder: Path):
    from tokenizers import Tokenizer

    return Tokenizer.from_file(str(folder / "tokenizer.json"))


def prune(folder: Path, data: Path | None) -> None:
    tok = _tokenizer(folder)
    texts = generator_strings() | (dataset_texts(data) if data is not None else set())
    ids = set()
    for enc in tok.encode_batch(sorted(texts)):
        ids.update(enc.ids)
    ids = np.asarray(sorted(ids), np.int64)
    tensors = load_file(str(folder / "model.safetensors"))
    emb = tensors.pop(KEY)
    np.savez(folder / "vocab_rows.npz", ids=ids, rows=emb[ids], shape=np.asarray(emb.shape))
    save_file(tensors, str(folder / "model.safetensors"))
    print(f"{len(texts)} texts and generator phrases use {len(ids)} of {emb.shape[0]} word "
          "pieces")


def check(folder: Path, data: Path) -> int:
    tok = _tokenizer(folder)
    with np.load(folder / "vocab_rows.npz") as z:
        kept = set(z["ids"].tolist())
    texts = sorted(dataset_texts(data))
    for text, enc in zip(texts, tok.encode_batch(texts)):
        missing = [t for i, t in zip(enc.ids, enc.tokens) if i not in kept]
        if missing:
            print(f"the pruned MiniLM in {folder} lacks the word piece {missing[0]!r} of "
                  f"{text!r} ({data}): run scripts/device/prepare.sh with this dataset "
                  "(prepare.sh SEG DATA_DIR) or add the word to the generator", file=sys.stderr)
            return 1
    print(f"all {len(texts)} texts of {data} are covered")
    return 0


def restore(folder: Path, out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    for f in folder.iterdir():
        if f.is_file() and f.name not in ("model.safetensors", "vocab_rows.npz"):
            shutil.copy(f, out / f.name)
    tensors = load_file(str(folder / "model.safetensors"))
    with np.load(folder / "vocab_rows.npz") as z:
        full = np.zeros(tuple(z["shape"]), z["rows"].dtype)
        full[z["ids"]] = z["rows"]
    save_file({**tensors, KEY: full}, str(out / "model.safetensors"))


if __name__ == "__main__":
    args = sys.argv[1:]
    if args[:1] == ["prune"] and len(args) in (2, 3):
        prune(Path(args[1]), Path(args[2]) if len(args) == 3 else None)
    elif args[:1] == ["check"] and len(args) == 3:
        sys.exit(check(Path(args[1]), Path(args[2])))
    elif args[:1] == ["restore"] and len(args) == 3:
        restore(Path(args[1]), Path(args[2]))
    else:
        sys.exit("usage: minilm_vocab.py prune DIR [DATA_DIR] | check DIR DATA_DIR | "
                 "restore DIR OUT")
