#!/usr/bin/env bash
# Renderer figures (BENCHMARKS.md, "Renderer"): the time of a 1280 × 720 stereo pair, and
# the perception front end on the 8 real LAC pairs beside rendered frames of held-out seeds
# (valid-disparity fraction, detections per frame, grey-level histogram distance).
#
# Writes the section "render" of BENCHMARKS.md (PRINT=1: prints it instead).
# usage: scripts/bench_render.sh [SEEDS (default "11 12 13")] [SUN_ELEVATION (default 10)]
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-target}"
SEEDS="${1:-11 12 13}"
SUN="${2:-10}"
DATA="${SEGLOC_DATA:-../shared/data}"
BIN="${SEGLOC_BIN:-$CARGO_TARGET_DIR/release/segloc}"
[ "${SKIP_BUILD:-0}" = 1 ] || [ -n "${SEGLOC_BIN:-}" ] || nice -n 10 cargo build --release -q
TMP="$(mktemp -d)"
trap 'rm -rf "$TMP"' EXIT
for s in $SEEDS; do
  "$BIN" sim render --seed "$s" --seconds 60 --every 100 --sun-elevation "$SUN" \
    -o "$TMP/seed$s" 2>>"$TMP/render.log"
  for left in "$TMP/seed$s"/*_0.png; do
    "$BIN" detect --left "$left" --right "${left%_0.png}_1.png" --json >>"$TMP/rendered.jsonl"
  done
done
for left in "$DATA"/lac-images/*_0.png; do
  "$BIN" detect --left "$left" --right "${left%_0.png}_1.png" --json >>"$TMP/real.jsonl"
done
section=$(python3 - "$TMP" "$SEEDS" "$SUN" <<'PY'
import json, re, statistics, sys
tmp, seeds, sun = sys.argv[1], sys.argv[2], sys.argv[3]
def load(name):
    return [json.loads(l) for l in open(f"{tmp}/{name}") if l.strip()]
def summary(rows):
    hist = [statistics.mean(r["gray_histogram"][k] for r in rows) for k in range(32)]
    return {
        "frames": len(rows),
        "valid": statistics.mean(r["valid_disparity_fraction"] for r in rows),
        "detections": statistics.mean(len(r["boulders"]) for r in rows),
        "hist": hist,
    }
real, rendered = summary(load("real.jsonl")), summary(load("rendered.jsonl"))
tv = lambda a, b: 0.5 * sum(abs(x - y) for x, y in zip(a, b))
ms = [float(m) for m in re.findall(r"median (\d+) ms a pair", open(f"{tmp}/render.log").read())]
import datetime, subprocess
sh = lambda c: subprocess.run(["sh", "-c", c], capture_output=True, text=True).stdout.strip()
cpu, commit, load = sh("lscpu | sed -n 's/Model name: *//p'"), sh("git rev-parse --short HEAD"), sh("cut -d' ' -f1-3 /proc/loadavg")
pair_ms = statistics.median(ms)
print("## Renderer (`segloc sim render`)\n")
print(f"`scripts/bench_render.sh` (seeds {seeds}, held out: nothing was tuned on them; sun {sun}°) — {datetime.date.today()}, "
      f"{cpu}, commit `{commit}`, load average {load} at the end. Front end: `segloc detect --json` (geometric segmenter).\n")
print("| | frames | valid disparity (lit pixels) | detections / frame |\n|---|---|---|---|")
for name, x in (("real LAC pairs (`lac-images`)", real), (f"rendered, seeds {seeds}, sun {sun}°", rendered)):
    print(f"| {name} | {x['frames']} | {x['valid']:.3f} | {x['detections']:.2f} |")
print(f"\n- Stereo pair at 1280 × 720: median {pair_ms:.0f} ms (per-seed medians {', '.join(f'{m:.0f}' for m in ms)}); "
      f"target ≤ 150 ms {'met' if pair_ms <= 150 else '**not met**'}.")
print(f"- Grey-level histogram distance (total variation of the mean 32-bin histograms), real against rendered: "
      f"{tv(real['hist'], rendered['hist']):.3f}; real sky pixels in bin 0: {real['hist'][0]:.2f}, rendered: {rendered['hist'][0]:.2f}.")
PY
)
if [[ "${PRINT:-0}" == 1 ]]; then echo "$section"; else echo "$section" | python3 scripts/bench_section.py render; fi
