#!/bin/bash
# One device call of an ADM (TASK=adm, the default), AMDM (TASK=amdm) or object-centric
# (TASK=trajectory | completion) training run on a lent
# GPU machine (see docs/results.md in the git history, "Fine-tuning the ADM on a GPU"). Idempotent: call it again
# and again (each call at most 10 minutes) while the machine stays warm; each call does what is
# left:
#   1. install the staged wheels (scripts/device/prepare.sh) into /tmp/site;
#   2. build the grown dataset (SCENES rooms, the first SPLIT split as before, the rest train)
#      with every CPU, JAX on the CPU (16 processes must not each take the GPU);
#   3. fill the text caches (scripts/device/encode_texts.py);
#   4. start training in its own session (setsid: it outlives the call while the machine is
#      held), resuming from .dev/run/ (unpacked from a previous call's files) on a fresh machine;
#   5. wait until LIMIT seconds have passed (or training ended), then copy the run's small files
#      to $OUT: the exported weights, best.json, metrics.jsonl, the logs. Each file there must be
#      under 16 MB, so the Orbax checkpoint (16+ MB with the optimiser state) stays behind:
#      resume on a fresh machine with init_from=<model.safetensors> instead.
# Device call:  LIMIT=550 [TASK=amdm] bash scripts/device/train.sh      (carry: [".dev"])
# Settings (environment): TASK, SCENES, SPLIT, D (work folder there), PHRASING (the
# instructions' phrasing, default | rich: jaxmotion synth --phrasing; the rich dataset is built
# in its own folder, $D/synth-rich), TRAIN_ARGS (key=value
# overrides appended to the defaults below, e.g. "crop.centre=room crop.size=8" for the room view,
# or "model.target_input=true" for the ADM that reads a known target, shipped since session 11).
# TASK=trajectory / TASK=completion continue the shipped object-centric models (same CPU size;
# the shipped completion model: TRAIN_ARGS="joint_weight=200 foot_contact_weight=3
# joint_velocity_weight=2", SCENES=2000 SPLIT=2000 to build in under 2 minutes;
# add TRAIN_ARGS="model.traj_sensor=true sensor_points=2048" and drop init_from for a completion
# model with the trajectory sensor, or preset=paper for the paper's size, from scratch).
# The shipped completion model reads the trajectory's velocity (docs/results.md in the git history, "The
# completion model told the trajectory's velocity"): TRAIN_ARGS="joint_weight=200
# foot_contact_weight=3 joint_velocity_weight=2 model.traj_velocity=true
# geometric_weighting=uniform" continues it.
# TASK=amdm trains the AMDM on the shipped ADM's maps (half the batches) with the temporal basis
# of the plausibility issue (model.temporal_basis=24: docs/results.md in the git history, "A band-limited AMDM"),
# from scratch; add
# TRAIN_ARGS="init_from=$PWD/jaxmotion/assets/amdm.safetensors" to fine-tune the shipped one.
set -u
export PYTHONUNBUFFERED=1
T0=$(date +%s)
LIMIT=${LIMIT:-550}
TASK=${TASK:-adm}
case "$TASK" in adm|amdm|trajectory|completion) ;;
  *) echo "TASK must be adm, amdm, trajectory or completion, got '$TASK'"; exit 2;; esac
SCENES=${SCENES:-5000}
SPLIT=${SPLIT:-2000}
PHRASING=${PHRASING:-default}
case "$PHRASING" in default|rich) ;;
  *) echo "PHRASING must be default or rich, got '$PHRASING'"; exit 2;; esac
D=${D:-/root/jm}
SYN=$D/synth$([ "$PHRASING" = rich ] && echo -rich)
PY=${PY:-python3}
OUT=${OUT:?set OUT, the folder whose files come back}
mkdir -p "$D" "$OUT"
NW=$(ls .dev/whl | wc -l)
if [ ! -f "/tmp/site/.ok$NW" ]; then
  $PY -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
    --target /tmp/site .dev/whl/*.whl && touch "/tmp/site/.ok$NW" || exit 1
fi
export PYTHONPATH=/tmp/site:$PWD JAXMOTION_MINILM_DIR=$PWD/.dev/minilm16 JAXMOTION_CACHE=$D/xla
if [ -f .dev/minilm16/vocab_rows.npz ]; then  # pruned by prepare.sh: put the rows back
  [ -f "$D/minilm/model.safetensors" ] || \
    $PY scripts/device/minilm_vocab.py restore .dev/minilm16 "$D/minilm" || exit 1
  export JAXMOTION_MINILM_DIR=$D/minilm
fi
echo "== $(date +%T) start; $(nproc) cpus"
$PY -c "import jax, flax; print('jax', jax.__version__, jax.devices(), 'flax', flax.__version__)" || exit 1
if [ ! -f "$SYN/manifest.json" ]; then
  echo "== $(date +%T) synth $SCENES rooms (split over the first $SPLIT), $PHRASING phrasing"
  JAX_PLATFORMS=cpu timeout $((LIMIT - 45 - ($(date +%s) - T0))) $PY -m jaxmotion synth \
    --out "$SYN" --scenes "$SCENES" --split-scenes "$SPLIT" --per-scene 10 --seed 0 \
    --phrasing "$PHRASING" --workers "$(nproc)" --no-stats > "$D/synth.log" 2>&1
  tail -c 300 "$D/synth.log"; echo
fi
if [ -f "$SYN/manifest.json" ]; then
  [ -f "$SYN/stats.npz" ] || cp .dev/stats.npz "$SYN/stats.npz"
  if [ ! -f "$SYN/encoded" ]; then
    if [ -f .dev/minilm16/vocab_rows.npz ]; then  # every word of the texts must have travelled
      $PY scripts/device/minilm_vocab.py check .dev/minilm16 "$SYN" || exit 1
    fi
    echo "== $(date +%T) encode"
    $PY scripts/device/encode_texts.py "$SYN" && touch "$SYN/encoded"
  fi
  if [ -f "$SYN/encoded" ] && ! pgrep -f "jaxmotion.train" > /dev/null; then
    echo "== $(date +%T) train"
    rm -f "$D/train.log"
    if [ "$TASK" = amdm ]; then
      TASK_ARGS="--config configs/amdm.py adm_workdir=$PWD/jaxmotion/assets/adm.safetensors
        model.temporal_basis=24 predicted_fraction=0.5 adm_sampler_steps=10"
    elif [ "$TASK" = trajectory ] || [ "$TASK" = completion ]; then
      TASK_ARGS="--config configs/$TASK.py model.temporal_basis=24
        init_from=$PWD/jaxmotion/assets/$TASK.safetensors"
    else
      TASK_ARGS="--config configs/adm.py backbone_workdir=$PWD/.dev/seg model.text_tokens=24
        init_from=$PWD/jaxmotion/assets/adm.safetensors grounding_every=500 grounding_cases=256"
    fi
    # shellcheck disable=SC2086  # TASK_ARGS and TRAIN_ARGS are word lists
    setsid nohup $PY -m jaxmotion.train $TASK_ARGS data_dir="$SYN" workdir="$D/run" \
      batch_size=64 steps=60000 optim.lr=1e-4 optim.warmup_steps=100 log_every=100 \
      eval_every=1000 ckpt_every=500 keep_checkpoints=1 loader_workers=12 \
      progress=false ${TRAIN_ARGS:-} > "$D/train.log" 2>&1 < /dev/null &
  fi
else
  LIMIT=0  # nothing to wait for: say what failed now
fi
while [ $(( $(date +%s) - T0 )) -lt "$LIMIT" ]; do
  sleep 10
  if [ -f "$D/train.log" ] && ! pgrep -f "jaxmotion.train" > /dev/null; then
    echo "training process ended"; break
  fi
done
echo "== $(date +%T) pack"
grep -v "^ " "$D/train.log" 2>/dev/null | tail -n 5
tail -n 3 "$D/run/metrics.jsonl" 2>/dev/null
for f in model.safetensors model_best.safetensors best.json metrics.jsonl config.json; do
  cp "$D/run/$f" "$OUT/" 2>/dev/null
done
cp "$D/train.log" "$D/synth.log" "$OUT/" 2>/dev/null
nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader 2>/dev/null
echo "== $(date +%T) end"
