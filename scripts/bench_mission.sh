#!/usr/bin/env bash
# The two-session mission on seeds 1-20 (quick: 1-5): per-seed figures and the summary
# BENCHMARKS.md quotes (wrong relocalizations, collisions, RMSE, LAC geometric and rocks).
# Usage: scripts/bench_mission.sh [--quick] [FIRST LAST]
set -euo pipefail
cd "$(dirname "$0")/.."
first=1 last=20
if [[ "${1:-}" == "--quick" ]]; then last=5; shift; fi
if [[ $# -ge 2 ]]; then first=$1 last=$2; fi
cargo build --release --bin segloc >/dev/null 2>&1
dir="$(mktemp -d)"
trap 'rm -rf "$dir"' EXIT
for s in $(seq "$first" "$last"); do
  target/release/segloc mission --seed "$s" --json > "$dir/m$s.json" 2>/dev/null
done
python3 - "$dir" "$first" "$last" <<'PY'
import json, sys, statistics, datetime, subprocess
d, first, last = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
cpu = subprocess.run(["sh", "-c", "lscpu | sed -n 's/Model name: *//p'"], capture_output=True, text=True).stdout.strip()
rows = []
print(f"`scripts/bench_mission.sh {first} {last}` — {datetime.date.today()}, {cpu}\n")
print("| seed | accepted / refused / wrong | collisions | S1 RMSE cm | S2 RMSE cm | geometric | rocks |")
print("|---|---|---|---|---|---|---|")
for s in range(first, last + 1):
    r = json.load(open(f"{d}/m{s}.json"))
    rel, lac = r["relocalizations"], r["lac"]
    s1, s2 = (100 * x["rmse_m"] for x in r["sessions"])
    rows.append((rel["wrong_accepted"], r["collisions"], s1, s2, lac["geometric"], lac["rocks"]))
    print(f"| {s} | {rel['accepted']} / {rel['refused']} / {rel['wrong_accepted']} | {r['collisions']} | {s1:.2f} | {s2:.2f} | {lac['geometric']:.1f} | {lac['rocks']:.1f} |")
col = list(zip(*rows))
print(f"\nwrong {sum(col[0])}, collisions {sum(col[1])}, S1 RMSE max {max(col[2]):.2f} cm, S2 RMSE max {max(col[3]):.2f} cm, "
      f"geometric min {min(col[4]):.1f} / mean {statistics.mean(col[4]):.2f}, rocks min {min(col[5]):.1f} / mean {statistics.mean(col[5]):.2f}")
PY
