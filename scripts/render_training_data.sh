#!/usr/bin/env bash
# Render the learned segmenter's training and validation frames (scripts/train_segmenter.py)
# with `segloc sim render --half`: each seed is another synthetic moon (its own rocks and
# sizes), with its own sun elevation (5–30°), sun azimuth, rock and regolith albedo and
# exposure, drawn from the seed so that the set is reproducible.
#
# awk's srand/rand gives neighbouring seeds similar first draws, so seeds 1..N_TRAIN have
# sun elevations of about 10–30° only; a low-sun batch (seeds 101..100+N_LOW, elevation
# 5–12°) fills the gap.
# Training seeds: 1..N_TRAIN and 101..100+N_LOW; validation seeds (held out, never trained
# on): 901..900+N_VAL.
# usage: scripts/render_training_data.sh OUT_DIR [N_TRAIN (38)] [N_VAL (4)] [N_LOW (10)]
#   env: SEGLOC_BIN (default $CARGO_TARGET_DIR/release/segloc), SECONDS_PER_SEED (60),
#        EVERY (40 ticks = 2 s), HALF (1: 640 × 360, the training size; 0: full 1280 × 720)
set -euo pipefail
cd "$(dirname "$0")/.."
OUT="${1:?usage: scripts/render_training_data.sh OUT_DIR [N_TRAIN] [N_VAL]}"
N_TRAIN="${2:-38}"
N_VAL="${3:-4}"
N_LOW="${4:-10}"
BIN="${SEGLOC_BIN:-${CARGO_TARGET_DIR:-target}/release/segloc}"
SECS="${SECONDS_PER_SEED:-60}"
EVERY="${EVERY:-40}"
HALF_FLAG=$([ "${HALF:-1}" = 1 ] && echo --half || true)
mkdir -p "$OUT/train" "$OUT/val"

render() { # seed dir [low]
  local seed="$1" dir="$2" low="${3:-0}"
  [ -f "$dir/rocks.json" ] && return 0
  # per-seed appearance, drawn from the seed (awk's srand is deterministic)
  read -r elev azim rock_albedo regolith exposure session < <(awk -v s="$seed" 'BEGIN{srand(s*7919+13);
    printf "%.1f %.1f %.2f %.2f %.0f %d\n", 5+25*rand(), 360*rand(), 0.8+0.7*rand(), 0.8+0.4*rand(), 150+250*rand(), 1+int(2*rand())}')
  if [ "$low" = 1 ]; then
    elev=$(awk -v s="$seed" 'BEGIN{srand(s*104729+7); rand(); printf "%.1f", 5+7*rand()}')
  fi
  local cfg="$OUT/render_$seed.toml"
  printf 'rock_albedo = %s\nregolith_albedo = %s\nexposure_dn = %s\nnoise_seed = %s\n' \
    "$rock_albedo" "$regolith" "$exposure" "$seed" >"$cfg"
  echo "seed $seed: sun elevation $elev, azimuth $azim, session $session, $(tr '\n' ' ' <"$cfg")" >&2
  nice -n 10 "$BIN" sim render --seed "$seed" --session "$session" --seconds "$SECS" --every "$EVERY" $HALF_FLAG \
    --sun-elevation "$elev" --sun-azimuth "$azim" --render-config "$cfg" -o "$dir" --overwrite >/dev/null
}

for s in $(seq 1 "$N_TRAIN"); do render "$s" "$OUT/train/seed$s"; done
for s in $(seq 101 $((100 + N_LOW))); do render "$s" "$OUT/train/seed$s" 1; done
for s in $(seq 901 $((900 + N_VAL))); do render "$s" "$OUT/val/seed$s"; done
echo "frames: train $(ls "$OUT"/train/*/*_0.png | wc -l), val $(ls "$OUT"/val/*/*_0.png | wc -l)" >&2
