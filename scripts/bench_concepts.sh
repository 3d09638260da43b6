#!/usr/bin/env bash
# Issue 31 (function length, typed errors): the one hot loop that was split, the SGM row
# sweep (`src/perception/sgm/sweep.rs`), timed by `segloc bench detect` on the 8 real LAC
# pairs, this build against a peer binary (the build before the split), rounds interleaved
# so that both see the same load. Prints a short markdown section (never writes
# BENCHMARKS.md); the count of functions over 100 lines is clippy's
# (`clippy::too_many_lines`, threshold in clippy.toml).
#
#   scripts/bench_concepts.sh PEER_BINARY [ROUNDS]   (default 3 rounds of 10 repeats each)
# Environment: SEGLOC_DATA (default ../shared/data), CARGO_TARGET_DIR, SEGLOC_BIN.
set -euo pipefail
cd "$(dirname "$0")/.."
peer="${1:?usage: $0 PEER_BINARY [ROUNDS]}"
rounds="${2:-3}"
images="${SEGLOC_DATA:-../shared/data}/lac-images"
[ -d "$images" ] || { echo "bench_concepts: no LAC images at $images (set SEGLOC_DATA)" >&2; exit 1; }
source scripts/bench_lib.sh
segloc_bin
dir="$(mktemp -d)"
trap 'rm -rf "$dir"' EXIT
load_start=$(cut -d' ' -f1 /proc/loadavg)
for r in $(seq "$rounds"); do
  "$bin" bench detect --images "$images" --repeat 10 --json > "$dir/this_$r.json"
  "$peer" bench detect --images "$images" --repeat 10 --json > "$dir/peer_$r.json"
done
load_end=$(cut -d' ' -f1 /proc/loadavg)
python3 - "$dir" "$rounds" "$load_start" "$load_end" <<'PY'
import json, sys, datetime, statistics, subprocess
d, rounds, load0, load1 = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
def med(kind, stage):
    return statistics.median(json.load(open(f"{d}/{kind}_{r}.json"))["all"]["ms"][stage]["median"]
                             for r in range(1, rounds + 1))
print("## Function length and typed errors (issue 31)\n")
print(f"`scripts/bench_concepts.sh PEER` — {datetime.date.today()}, AMD EPYC, 2 cores, commit `{commit}`, "
      f"load average {load0} → {load1}; `segloc bench detect` on the 8 LAC pairs, {rounds} interleaved rounds "
      "of 10 repeats, median of the rounds' medians.\n")
print("| stage | this build | peer (before the split) | ratio |")
print("|---|---|---|---|")
for stage in ["total", "stereo", "cpu"]:
    a, b = med("this", stage), med("peer", stage)
    print(f"| {stage} | {a:.1f} ms | {b:.1f} ms | {a / b:.3f} |")
print("\nThe SGM row sweep was split (costs of a column, end of row) into `#[inline(always)]` helpers. "
      "Outputs before / after: identical for `detect` (8 pairs), `eval lunarloc --pairs paper --trials 5` and "
      "`graph optimize sphere2500`; `mission --seed 1..5` identical but for `sessions[].rmse_m` in its last "
      "digits (≤ 3e-14 relative), which varies as much (≤ 6e-14) between two runs of the same binary.")
PY
