#!/usr/bin/env bash
# Global localization against the LAC ground-truth rock grid (issue 29): every LunarLoc
# traverse, its 60 s submaps and its mirror image against the grid's rocks at 0.15, 0.3
# and 0.45 m cells, and the time of a 2,000-rock prior. Writes the section "grid" of
# BENCHMARKS.md (--print: prints it instead); the JSON stays in target/bench/grid.
#
#   scripts/bench_grid.sh [--print]   (from anywhere; SEGLOC_DATA, default ../shared/data;
#                                      TRIALS transforms per traverse, default 20;
#                                      REUSE=1 keeps a run whose JSON is already there)
set -euo pipefail
repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo_root"
data="${SEGLOC_DATA:-../shared/data}"
[ -d "$data/lunarloc" ] || { echo "bench_grid: no LunarLoc data at $data (set SEGLOC_DATA)" >&2; exit 1; }
source scripts/bench_lib.sh
segloc_bin
out="$target/bench/grid"
mkdir -p "$out"
export RAYON_NUM_THREADS=1
trials="${TRIALS:-20}"
for cell in 0.15 0.3 0.45; do
  [[ "${REUSE:-0}" == 1 && -s "$out/grid_$cell.json" ]] && continue
  echo "[bench_grid] $cell m grid" >&2
  nice -n 10 "$bin" eval grid --data "$data" --cell-size "$cell" --trials "$trials" --submaps --negatives --json > "$out/grid_$cell.json"
done
echo "[bench_grid] 2,000-rock prior" >&2
[[ "${REUSE:-0}" == 1 && -s "$out/grid_2000.json" ]] ||
nice -n 10 "$bin" eval grid --data "$data" --cell-size 0.15 --trials 1 --extra-rocks 1422 --json > "$out/grid_2000.json"

section=$(python3 - "$out" "$(date -u '+%Y-%m-%d %H:%M UTC')" "$(git rev-parse --short HEAD)" "$trials" <<'PY'
import json, sys
out, date, commit, trials = sys.argv[1:5]
R = {c: json.load(open(f"{out}/grid_{c}.json")) for c in ("0.15", "0.3", "0.45")}
big = json.load(open(f"{out}/grid_2000.json"))
w = print
w("## Global localization against the rock grid (no prior session)")
w("")
w(f"`scripts/bench_grid.sh` ({date}, commit `{commit}`, AMD EPYC, 2 cores, one thread: `RAYON_NUM_THREADS=1`; "
  "CPU ms = process CPU time per query, the machine being shared). Per cell size: "
  f"`segloc eval grid --cell-size C --trials {trials} --submaps --negatives`; every traverse under {trials} random rigid "
  f"transforms, every 60 s submap under one, every mirrored traverse under {trials}. The defaults were chosen on "
  "traverses 3, 7, 13 and 16 at 0.15 m (seed 1); the other traverses, the submaps and the mirrors are held out.")
w("")
w("| cell | rocks | traverses all ≤5 cm/0.3° | all ≤15 cm | trials ≤5 cm / ≤15 cm / wrong / refused | median CPU ms (wall) | submaps placed ≤5 cm / refused / wrong | negatives accepted |")
w("|---|---|---|---|---|---|---|---|")
for c, r in R.items():
    t, s, n = r["traverses"], r["submaps"], r["negatives"]
    w(f"| {c} m | {r['prior_landmarks']} | {t['traverses_all_within_5cm']}/17 | {t['traverses_all_within_15cm']}/17 | "
      f"{t['within_5cm']} / {t['within_15cm']} / {t['wrong']} / {t['refused']} of {t['queries']} | "
      f"{t['cpu_ms_median']:.0f} ({t['time_ms_median']:.0f}) | "
      f"{s['within_5cm']/max(s['queries'],1):.0%} / {s['refused']/max(s['queries'],1):.0%} / {s['wrong']} of {s['queries']} | "
      f"{n['accepted']} of {n['queries']} |")
bt = big["traverses"]
w("")
w(f"2,000-rock prior (the 0.15 m grid's {R['0.15']['prior_landmarks']} rocks plus synthetic ones, "
  f"`--extra-rocks 1422 --trials 1`): median CPU {bt['cpu_ms_median']:.0f} ms (wall {bt['time_ms_median']:.0f} ms), "
  f"{bt['within_5cm']} of {bt['queries']} within 5 cm, {bt['wrong']} wrong.")
w("Traverses: error at the world origin (the lander), as `eval lunarloc`; submaps: at the rover's own positions. "
  "Wrong = accepted and off by more than max(10 cm, a third of a cell) or 1°, or any accepted negative.")
PY
)
if [[ "${1:-}" == "--print" ]]; then echo "$section"; else echo "$section" | python3 scripts/bench_section.py grid; fi
