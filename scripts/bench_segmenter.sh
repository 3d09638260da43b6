#!/usr/bin/env bash
# Learned vs geometric segmenter: recall / precision on the 8 real LAC pairs against the hand
# labels (tests/fixtures/real_rock_labels.csv), and on held-out rendered seeds against the
# renderer's truth (scripts/eval_rendered_segmenter.py), plus the learned front end's time
# (one-off runs and steady state).
# Writes the section "segmenter" of BENCHMARKS.md (with --print: prints it instead).
#
# usage: scripts/bench_segmenter.sh [--print] [VAL_DIR (default: renders held-out seeds 901-904 at
#        1280 × 720 into a temp dir, the appearance drawn as for the training frames)]
# env:   SEGLOC_BIN (default $CARGO_TARGET_DIR/release/segloc), PYTHON (needs numpy, pillow)
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-target}"
BIN="${SEGLOC_BIN:-$CARGO_TARGET_DIR/release/segloc}"
PY="${PYTHON:-python3}"
DATA="${SEGLOC_DATA:-../shared/data}"
LABELS=tests/fixtures/real_rock_labels.csv
TMP="$(mktemp -d)"
trap 'rm -rf "$TMP"' EXIT
print=0
if [[ "${1:-}" == "--print" ]]; then print=1; shift; fi
VAL="${1:-}"
if [ -z "$VAL" ]; then
  VAL="$TMP/data"
  HALF=0 EVERY=60 SEGLOC_BIN="$BIN" scripts/render_training_data.sh "$VAL" 0 4 0 2>/dev/null
  VAL="$VAL/val"
fi
for s in geometric learned; do
  "$BIN" eval segmenter --labels "$LABELS" --data "$DATA" --segmenter "$s" --json >"$TMP/real_$s.json"
  "$PY" scripts/eval_rendered_segmenter.py "$BIN" "$s" "$VAL"/seed* --json >"$TMP/rendered_$s.json"
done
# the learned front end's time: one-off `segloc detect` runs (3 rounds over the 8 pairs) and
# the steady state of `segloc bench detect`
load_start=$(cut -d' ' -f1 /proc/loadavg)
for r in 1 2 3; do
  for left in "$DATA"/lac-images/*_0.png; do
    "$BIN" detect --segmenter learned --left "$left" --right "${left%_0.png}_1.png" --json >>"$TMP/oneoff.jsonl"
  done
done
"$BIN" bench detect --segmenter learned --images "$DATA/lac-images" --repeat 5 --json >"$TMP/steady.json"
load_end=$(cut -d' ' -f1 /proc/loadavg)
section=$("$PY" - "$TMP" "$LABELS" "$VAL" "$load_start" "$load_end" <<'PY'
import datetime, json, statistics, sys
tmp, labels, val, load0, load1 = sys.argv[1:6]
real = {s: json.load(open(f"{tmp}/real_{s}.json")) for s in ("geometric", "learned")}
rend = {s: json.load(open(f"{tmp}/rendered_{s}.json")) for s in ("geometric", "learned")}
print("## Segmenters: learned (U-Net, models/boulders.onnx) vs geometric\n")
print(f"{datetime.date.today()}, AMD EPYC, 2 cores. Real: 8 LAC pairs vs {labels} "
      f"({real['learned']['total']['rocks']} rocks within 8 m). Rendered: validation seeds 901-904 (never trained on; they pick the exported checkpoint; 1280 x 720 unless VAL_DIR is given), "
      "rocks >= 10 cm within 6 m.\n")
print("| segmenter | real recall | real precision | rendered recall | rendered precision | centroid error (median) | segment ms/pair |")
print("|---|---|---|---|---|---|---|")
for s in ("geometric", "learned"):
    r, g = real[s], rend[s]
    ce = g["centroid_error_median_m"]
    print(f"| {s} | {r['recall']:.2f} | {r['precision']:.2f} | {g['recall']:.2f} | {g['precision']:.2f} | "
          f"{'-' if ce is None else f'{ce*100:.1f} cm'} | {r['mean_segment_ms']:.0f} |")
print()
pairs = " ".join(
    f"{p['pair']} {p['score']['found']}/{p['score']['rocks']} fp {p['score']['false_positives']};"
    for p in real["learned"]["pairs"])
print(f"Learned per pair (found/rocks, false positives): {pairs}")
pairs = " ".join(
    f"{p['pair']} {p['score']['found']}/{p['score']['rocks']} fp {p['score']['false_positives']};"
    for p in real["geometric"]["pairs"])
print(f"Geometric per pair: {pairs}\n")
oneoff = sorted(json.loads(l)["time_ms"] for l in open(f"{tmp}/oneoff.jsonl"))
steady = json.load(open(f"{tmp}/steady.json"))
ms = steady["all"]["ms"]
print(f"Learned front end (stereo, network, boulders with the stereo check), 2 threads, load {load0} → {load1}: "
      f"one-off `segloc detect --segmenter learned` over the 8 pairs × 3: median {statistics.median(oneoff):.0f} ms "
      f"(min {oneoff[0]:.0f}, max {oneoff[-1]:.0f}; {sum(t <= 100 for t in oneoff)} of {len(oneoff)} ≤ 100 ms); "
      f"steady `segloc bench detect --segmenter learned`: median {ms['total']['median']:.1f} ms, p90 {ms['total']['p90']:.1f} "
      f"(stereo {ms['stereo']['median']:.1f}, network + decoder {ms['segment']['median']:.1f}, boulders {ms['boulders']['median']:.1f}); "
      f"first frame of that process {steady['first_frame_ms']['total_ms']:.0f} ms (stereo {steady['first_frame_ms']['stereo_ms']:.0f}). Target ≤ 100 ms both ways.\n")
print("Command: `scripts/bench_segmenter.sh` (real pairs: `segloc eval segmenter --labels "
      f"{labels} --segmenter S`; rendered: `scripts/eval_rendered_segmenter.py`).")
PY
)
if [[ $print == 1 ]]; then echo "$section"; else echo "$section" | python3 scripts/bench_section.py segmenter; fi
