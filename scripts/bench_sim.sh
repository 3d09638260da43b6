#!/usr/bin/env bash
# One simulated session on the synthetic moon (`segloc sim session --seed S --seconds 600
# --json`), seeds 1-10 (quick: 1-3): real-time factor, collisions, distance, odometry drift,
# detections. Writes the section "sim" of BENCHMARKS.md.
#
#   scripts/bench_sim.sh [--quick] [--print]
# Environment: CARGO_TARGET_DIR, SEGLOC_BIN.
set -euo pipefail
cd "$(dirname "$0")/.."
last=10 print=0
for a in "$@"; do
  case "$a" in
    --quick) last=3 ;;
    --print) print=1 ;;
    *) echo "usage: $0 [--quick] [--print]" >&2; exit 2 ;;
  esac
done
source scripts/bench_lib.sh
segloc_bin
dir="$(mktemp -d)"
trap 'rm -rf "$dir"' EXIT
load_start=$(cut -d' ' -f1 /proc/loadavg)
for s in $(seq 1 "$last"); do
  "$bin" sim session --seed "$s" --seconds 600 --json > "$dir/s$s.json"
done
section=$(python3 - "$dir" "$last" "$load_start" "$(cut -d' ' -f1 /proc/loadavg)" <<'PY'
import json, sys, datetime, subprocess, statistics
d, last, load0, load1 = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
rs = [json.load(open(f"{d}/s{s}.json")) for s in range(1, last + 1)]
sh = lambda c: subprocess.run(["sh", "-c", c], capture_output=True, text=True).stdout.strip()
cpu, commit = sh("lscpu | sed -n 's/Model name: *//p'"), sh("git rev-parse --short HEAD")
rt = [r["realtime_factor"] for r in rs]
dist = [r["distance_m"] for r in rs]
drift = [100 * r["odometry_drift_fraction"] for r in rs]
det = [r["detections"] for r in rs]
rocks = [r["distinct_rocks"] for r in rs]
print("## Simulation: one session on the synthetic moon\n")
print(f"`scripts/bench_sim.sh` (= `segloc sim session --seed S --seconds 600 --json`, seeds 1–{last}) — "
      f"{datetime.date.today()}, {cpu}, commit `{commit}`, load average {load0} → {load1}. Default `MoonConfig` "
      "(40 m × 40 m, 0.1 m height field, 35 craters, 500 rocks of radius 0.05–0.5 m) and `SessionConfig` (20 Hz, "
      "camera frames at 1 Hz, the planner's 41 arcs at 0.4 m/s).\n")
print(f"| seeds 1–{last} | measured | target |\n|---|---|---|")
print(f"| real-time factor, median / min | **{statistics.median(rt):.0f}×** / {min(rt):.0f}× | ≥ 100× |")
print(f"| collisions (rock r ≥ 0.08 m, lander), ticks out of bounds | {sum(r['collisions'] for r in rs)}, "
      f"{sum(r['out_of_bounds_ticks'] for r in rs)} | 0 |")
print(f"| distance driven, min / median / max | {min(dist):.0f} / {statistics.median(dist):.0f} / {max(dist):.0f} m | — |")
print(f"| visual-odometry drift model, median / max | {statistics.median(drift):.2f} / {max(drift):.2f} % of the distance | — |")
print(f"| detections / distinct rocks a session, min–max | {min(det):,}–{max(det):,} / {min(rocks)}–{max(rocks)} | — |")
PY
)
if [[ $print == 1 ]]; then echo "$section"; else echo "$section" | python3 scripts/bench_section.py sim; fi
