#!/usr/bin/env bash
# Map merging with the real LunarLoc traverses as agents. Writes the section of
# BENCHMARKS.md between <!-- merge:begin --> and <!-- merge:end --> (nothing else).
#
#   scripts/bench_merge.sh [--print]       (from anywhere; --print: print, do not write)
# Environment: SEGLOC_DATA (default ../shared/data, relative to the repo root).
set -euo pipefail
repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo_root"
source scripts/bench_lib.sh
need_data lunarloc bench_merge
segloc_bin
out="$target/bench"
mkdir -p "$out"
echo "[bench_merge] 5 agents + 1 decoy, 100 trials" >&2
$bin eval merge --data "$data" --agents 5 --decoys 1 --trials 100 --seed 1 --json > "$out/merge5.json"
$bin eval merge --data "$data" --agents 5 --decoys 1 --trials 100 --seed 3 --json > "$out/merge5b.json"
echo "[bench_merge] all 17 agents + 2 decoys, 3 trials" >&2
$bin eval merge --data "$data" --agents 17 --decoys 2 --trials 3 --seed 2 --json > "$out/merge17.json"
echo "[bench_merge] rock map of the merged 17-traverse map" >&2
$bin eval merge --data "$data" --rock-map --seed 2 --json > "$out/merge_rocks.json"
section=$(python3 - "$out" "$(date -u '+%Y-%m-%d %H:%M UTC')" "$(lscpu | sed -n 's/^Model name: *//p' | head -1), $(nproc) cores" "$(git rev-parse --short HEAD)" "$(cut -d' ' -f1-3 /proc/loadavg)" <<'PY'
import json, sys
out, date, machine, commit, load = sys.argv[1:6]
m5 = json.load(open(f"{out}/merge5.json")); m5b = json.load(open(f"{out}/merge5b.json")); m17 = json.load(open(f"{out}/merge17.json"))
L = []
w = L.append
w("## Map merging: LunarLoc traverses as agents")
w("")
w(f"Command: `scripts/bench_merge.sh` (writes this section only). Date: {date}. Machine: {machine} "
  f"(load average {load} at the end: other jobs shared it). Commit `{commit}`. Times are wall clock, both cores.")
w("")
w("Each agent is one traverse moved by its own random rigid transform (any yaw, ±20 m, ±1 m) and fused into a map in "
  "its moved frame; the merge places every map in the first one's frame. Placement error: translation of "
  "`estimate · truth⁻¹` in the world frame (at the lander) and its rotation. Decoys are traverses mirrored in x: "
  "the statistics of a real map, but no rigid motion matches them to anything, so they must be reported "
  "disconnected.")
w("")
w("| run | agents placed | outside 1 cm / 0.1° | decoys placed | translation error mean / median / max (cm) | rotation mean / max | merge time median / max (ms) | landmarks (fused from ≥ 2), first trial |")
w("|---|---|---|---|---|---|---|---|")
def row(r, cmd):
    te, re_, t = r['translation_error_m'], r['rotation_error_deg'], r['time_ms']
    w(f"| `{cmd}` | {r['placed']}/{r['agents']} | **{r['placed_outside_1cm_0p1deg']}** | **{r['decoys_placed']}/{r['decoys']}** "
      f"| {100*te['mean']:.2f} / {100*te['median']:.2f} / {100*te['max']:.2f} | {re_['mean']:.3f}° / {re_['max']:.3f}° "
      f"| {t['median']:.0f} / {t['max']:.0f} | {r['trials'][0]['landmarks']} ({r['trials'][0]['fused']}) |")
row(m5, "segloc eval merge --agents 5 --decoys 1 --trials 100 --seed 1")
row(m5b, "segloc eval merge --agents 5 --decoys 1 --trials 100 --seed 3")
row(m17, "segloc eval merge --agents 17 --decoys 2 --trials 3 --seed 2")
w("")
w("Agents placed exclude the reference map. Viewpoint bias (default): each detection is pushed 0.8 cm away from the "
  "rover along its line of sight before fusing, each landmark's covariance gains (1 cm)² along its mean line of sight, "
  "and a pairwise transform with fewer than 10 inliers must fit to 2 cm ([design note](docs/design/viewpoint-bias.md)).")
w("")
rk = json.load(open(f"{out}/merge_rocks.json"))
w("**Rock map of the merged map**: `segloc eval merge --rock-map --seed 2`: all 17 traverses merged (each from its own random frame), the merged "
  "landmarks turned into a LAC rock grid (`mapping::rock_grid`, the same method for every map) and scored against "
  "the ground truth, beside each single traverse's map made the same way.")
w("")
w(f"- merged map: rock F1 **{rk['merged_f1']:.3f}** (precision {rk['merged_precision']:.3f}, recall {rk['merged_recall']:.3f})")
w(f"- best single traverse: {rk['best_single'][0]} with F1 {rk['best_single'][1]:.3f}; all: " + ", ".join(f"{n}: {f:.3f}" for n, f in rk['single_f1']))
w("")
print("\n".join(L))
PY
)
if [[ "${1:-}" == "--print" ]]; then echo "$section"; else echo "$section" | python3 scripts/bench_section.py merge; fi
