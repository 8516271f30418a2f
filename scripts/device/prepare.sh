#!/bin/bash
# Stage what an ADM training run on a lent GPU machine needs into .dev/ (git-ignored), on this
# machine, before the first device call. The device image has JAX 0.11 (+ CUDA), PyTorch,
# numpy, scipy, tokenizers, safetensors and tensorstore, no network, and a 64 MiB limit on what
# travels. So:
#   - wheels: flax 0.12.12 (flax 0.12.8, our CPU pin, fails on JAX 0.11: no
#     jax.experimental.hijax.HiPrimitive), the optax / orbax pins, and the pure-Python packages
#     the image lacks (trimesh, jaxopt, tensorboardX, mannequin-x, nanomanifold);
#   - the MiniLM weights as float16 (44 MB; the float32 ones are 87 MB): token states differ by
#     ~1e-3 relative, below the float16 rounding of the token cache (JAXMOTION_MINILM_DIR);
#     of the word-embedding matrix only the rows the instruction generator's words (either
#     phrasing, PHRASING=rich in train.sh too) and DATA_DIR's texts use travel (22 MB in all;
#     scripts/device/minilm_vocab.py, put back by train.sh, which checks that every text of
#     the dataset it builds is covered before it encodes);
#   - the segmentation backbone's weights and the 2,000-room set's stats.npz (the normalisation
#     the shipped models use).
# Usage: bash scripts/device/prepare.sh [SEGMENTATION_WORKDIR] [DATA_DIR]
set -euo pipefail
cd "$(git rev-parse --show-toplevel)"
SEG=${1:-runs/segmentation}
DATA=${2:-data/synth}
grep -qx "/.dev/" .git/info/exclude 2>/dev/null || { mkdir -p .git/info; echo "/.dev/" >> .git/info/exclude; }
mkdir -p .dev/whl .dev/minilm16 .dev/seg
python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
  --platform manylinux_2_17_x86_64 -d .dev/whl flax==0.12.12 optax==0.2.8 orbax-checkpoint==0.12.8 \
  trimesh==5.2.0 jaxopt==0.8.5 tensorboardX==2.6.5 mannequin-x==0.3.0 nanomanifold==0.8.0
if [ -f "$SEG/model.safetensors" ]; then cp "$SEG/model.safetensors" .dev/seg/; else echo "no $SEG: fine for TASK=amdm; an ADM run needs the backbone"; fi
cp "$DATA/stats.npz" .dev/stats.npz
python3 - <<'PY'
import shutil
import numpy as np
from safetensors.numpy import load_file, save_file
from jaxmotion.text.minilm import minilm_dir
src = minilm_dir()
for name in ("tokenizer.json", "config.json", "sentence_bert_config.json"):
    shutil.copy(src / name, ".dev/minilm16/" + name)
save_file({k: v.astype(np.float16) for k, v in load_file(str(src / "model.safetensors")).items()},
          ".dev/minilm16/model.safetensors")
PY
# the word-embedding rows the generator's words and the dataset's texts use, not all 30,522
# (23 MB less; exact for them)
python3 scripts/device/minilm_vocab.py prune .dev/minilm16 "$DATA"
du -sh .dev
echo "staged; the repo and .dev together must stay under 64 MiB"
