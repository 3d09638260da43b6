#!/usr/bin/env bash
# The mission with session 1 started lost against its site's rock grid
# (`segloc mission --seed S --session1-start lost-vs-grid --json`) next to the known-start
# mission (`segloc mission --seed S --json`) on seeds 1-10: prints a short markdown section
# (also written to $dir/section.md; BENCHMARKS.md is not touched). The per-seed reports stay
# in target/bench/mission_grid/ (known/mS.json, lost/mS.json).
#
# Usage: scripts/bench_mission_grid.sh [--print] [--from DIR] [FIRST LAST]
#   --print     only print the section from the reports already in DIR (no missions run)
#   --from DIR  the reports' directory (default $CARGO_TARGET_DIR/bench/mission_grid)
set -euo pipefail
cd "$(dirname "$0")/.."
first=1 last=10 print=0 from=""
while [[ $# -gt 0 ]]; do
  case "$1" in
    --print) print=1; shift ;;
    --from) from="$2"; shift 2 ;;
    *) first=$1 last=$2; shift 2 ;;
  esac
done
source scripts/bench_lib.sh
dir="${from:-$target/bench/mission_grid}"
if [[ $print == 0 ]]; then
  segloc_bin
  mkdir -p "$dir/known" "$dir/lost"
  for s in $(seq "$first" "$last"); do
    "$bin" mission --seed "$s" --json > "$dir/known/m$s.json" 2>/dev/null
    "$bin" mission --seed "$s" --session1-start lost-vs-grid --json > "$dir/lost/m$s.json" 2>/dev/null
  done
fi
python3 - "$dir" "$first" "$last" <<'PY' > "$dir/section.md"
import json, sys, datetime, subprocess
d, first, last = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
sh = lambda c: subprocess.run(["sh", "-c", c], capture_output=True, text=True).stdout.strip()
commit = sh("git rev-parse --short HEAD")
def fig(r):
    s1, s2 = r["sessions"]
    return dict(wrong=r["relocalizations"]["wrong_accepted"], coll=r["collisions"],
                s1=100 * s1["rmse_m"], s2=100 * s2["rmse_m"],
                geo=r["lac"]["geometric"], rocks=r["lac"]["rocks"], lost=s1.get("lost_start"))
print("## Mission, session 1 lost against the site's rock grid (`--session1-start lost-vs-grid`)\n")
print(f"`scripts/bench_mission_grid.sh` (= `segloc mission --seed S [--session1-start lost-vs-grid] --json`, "
      f"seeds {first}–{last}) — {datetime.date.today()}, AMD EPYC, 2 cores, commit `{commit}`. Ranges over the seeds. "
      "Grid fixes: accepted / refused / wrong (> 10 cm or 1°) against the "
      "0.15 m ground-truth grid; 'wrong (all)' adds both sessions' loop closures and relocalizations. The end's fit onto the grid was built on seeds 1–3; 4–10 held out.\n")
rows = []
for s in range(first, last + 1):
    k = fig(json.load(open(f"{d}/known/m{s}.json")))
    l = fig(json.load(open(f"{d}/lost/m{s}.json")))
    rows.append((s, k, l))
def span(side, key, fmt="{:.2f}"):
    v = [r[side][key] for r in rows]
    return f"{fmt.format(min(v))}–{fmt.format(max(v))}"
def total(side, key):
    return sum(r[side][key] for r in rows)
def seeds_where(pred):
    return ", ".join(str(s) for s, k, l in rows if pred(k, l)) or "none"
grid = [l["lost"] for _, _, l in rows]
fixes = [g["fixes"] for g in grid]
first_fix = [g["first_fix_s"] for g in grid if g["first_fix_s"] is not None]
print("| figure | known start | lost start |")
print("|---|---|---|")
print(f"| session 1 placed by the grid; first fix | — | {len(first_fix)}/{len(rows)}; {min(first_fix):.0f}–{max(first_fix):.0f} s |")
print(f"| grid fixes accepted / refused / **wrong** (> 10 cm or 1°) | — | {sum(f['accepted'] for f in fixes)} / "
      f"{sum(f['refused'] for f in fixes)} / **{sum(f['wrong_accepted'] for f in fixes)}** |")
print(f"| wrong, all relocalizations and loop closures | {total(0 + 1, 'wrong')} | {total(2, 'wrong')} (seeds: {seeds_where(lambda k, l: l['wrong'] > 0)}) |")
print(f"| collisions | {total(1, 'coll')} | {total(2, 'coll')} |")
print(f"| S1 / S2 RMSE, cm | {span(1, 's1')} / {span(1, 's2')} | {span(2, 's1')} / {span(2, 's2')} |")
print(f"| LAC geometric; rocks | {span(1, 'geo', '{:.1f}')}; {span(1, 'rocks', '{:.1f}')} | {span(2, 'geo', '{:.1f}')}; {span(2, 'rocks', '{:.1f}')} |")
PY
python3 -c 'import sys; sys.path.insert(0, "scripts"); from bench_section import write_section; write_section("BENCHMARKS.md", "mission-grid", sys.stdin.read())' < "$dir/section.md"
cat "$dir/section.md"
