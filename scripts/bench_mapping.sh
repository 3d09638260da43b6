#!/usr/bin/env bash
# The LAC rock map from the 17 real LunarLoc traverses (`segloc grid rocks`), scored against
# the LAC ground truth (`segloc grid score`), with the 4-sector cross-validation of its two
# thresholds (`segloc grid tune`). Writes the section "mapping" of BENCHMARKS.md.
#
#   scripts/bench_mapping.sh [--print]     (--print: print the section instead of writing it)
# Environment: SEGLOC_DATA (default ../shared/data), CARGO_TARGET_DIR, SEGLOC_BIN.
set -euo pipefail
cd "$(dirname "$0")/.."
data="${SEGLOC_DATA:-../shared/data}"
truth="$data/lac-groundtruth/moon_map_01_preset_1.csv"
[ -f "$truth" ] || { echo "bench_mapping: no LAC ground truth at $truth (set SEGLOC_DATA)" >&2; exit 1; }
source scripts/bench_lib.sh
segloc_bin
dir="$(mktemp -d)"
trap 'rm -rf "$dir"' EXIT
traverses=()
for n in $(seq 1 17); do traverses+=("$data/lunarloc/traverse_$n.csv"); done
started=$(date +%s.%N)
"$bin" grid rocks --traverses "${traverses[@]}" -o "$dir/rocks.csv" >/dev/null 2>&1
rocks_s=$(python3 -c "print(f'{$(date +%s.%N) - $started:.2f}')")
"$bin" grid score "$dir/rocks.csv" --groundtruth "$truth" --json > "$dir/score.json"
"$bin" grid tune --traverses "${traverses[@]}" --groundtruth "$truth" --json > "$dir/tune.json"
section=$(python3 - "$dir" "$rocks_s" <<'PY'
import json, sys, datetime, subprocess
d, rocks_s = sys.argv[1:3]
score, tune = json.load(open(f"{d}/score.json")), json.load(open(f"{d}/tune.json"))
sh = lambda c: subprocess.run(["sh", "-c", c], capture_output=True, text=True).stdout.strip()
cpu, commit = sh("lscpu | sed -n 's/Model name: *//p'"), sh("git rev-parse --short HEAD")
cv = tune["cross_validation"]["held_out"]
cfg = tune["config"]
print("## LAC rock map from the real LunarLoc detections\n")
print(f"`scripts/bench_mapping.sh` (= `segloc grid rocks --traverses traverse_{{1..17}}.csv`, `segloc grid score "
      f"--groundtruth moon_map_01_preset_1.csv`, `segloc grid tune`) — {datetime.date.today()}, {cpu}, commit `{commit}`; "
      f"the whole map in {rocks_s} s. The ground truth has 848 rock cells; detections touch 537 of them, so about "
      "0.775 is the F1 ceiling of any method marking only touched cells.\n")
print("| rock map from the 17 traverses | precision | recall | F1 | TP | FP | FN |\n| --- | --- | --- | --- | --- | --- | --- |")
print(f"| **defaults (repeats within {100 * cfg['repeat_radius_m']:g} cm, `min_hits` {cfg['min_hits']}, `min_rate` {cfg['min_rate']:g})** "
      f"| **{score['rock_precision']:.3f}** | **{score['rock_recall']:.3f}** | **{score['rock_f1']:.4f}** "
      f"| {score['true_positives']} | {score['false_positives']} | {score['false_negatives']} |")
print(f"| same, {tune['cross_validation']['folds']}-sector cross-validation (thresholds re-chosen per fold) "
      f"| {cv['precision']:.3f} | {cv['recall']:.3f} | {cv['f1']:.4f} | {cv['tp']} | {cv['fp']} | {cv['fn_']} |")
met = "reached" if score["rock_f1"] >= 0.65 else "**not reached**"
print(f"\nTarget F1 ≥ 0.65: {met} in-sample ({score['rock_f1']:.3f}), {cv['f1']:.3f} cross-validated (the held-out "
      "sectors). Method, thresholds and where the error lies: [design note](docs/design/rock-evidence.md).")
PY
)
if [[ "${1:-}" == "--print" ]]; then echo "$section"; else echo "$section" | python3 scripts/bench_section.py mapping; fi
