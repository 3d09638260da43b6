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
      f"seeds {first}–{last}) — {datetime.date.today()}, AMD EPYC, 2 cores, commit `{commit}`. Each cell: "
      "known start → lost start. Grid fixes: accepted / refused / wrong (> 10 cm or 1°) against the "
      "0.15 m ground-truth grid; 'wrong (all)' adds both sessions' loop closures and relocalizations. The end's fit onto the grid was built on seeds 1–3; 4–10 held out.\n")
print("| seed | S1 first fix | grid fixes | wrong (all) | collisions | S1 RMSE cm | S2 RMSE cm | LAC geometric | LAC rocks |")
print("|---|---|---|---|---|---|---|---|---|")
tot = dict(wrong=[0, 0], coll=[0, 0], gw=0, placed=0)
for s in range(first, last + 1):
    k = fig(json.load(open(f"{d}/known/m{s}.json")))
    l = fig(json.load(open(f"{d}/lost/m{s}.json")))
    g = l["lost"]
    ff = "never" if g["first_fix_s"] is None else f"{g['first_fix_s']:.0f} s"
    fx = g["fixes"]
    tot["wrong"][0] += k["wrong"]; tot["wrong"][1] += l["wrong"]
    tot["coll"][0] += k["coll"]; tot["coll"][1] += l["coll"]
    tot["gw"] += fx["wrong_accepted"]; tot["placed"] += g["first_fix_s"] is not None
    print(f"| {s} | {ff} | {fx['accepted']} / {fx['refused']} / **{fx['wrong_accepted']}** | "
          f"{k['wrong']} → {l['wrong']} | {k['coll']} → {l['coll']} | {k['s1']:.2f} → {l['s1']:.2f} | "
          f"{k['s2']:.2f} → {l['s2']:.2f} | {k['geo']:.1f} → {l['geo']:.1f} | {k['rocks']:.1f} → {l['rocks']:.1f} |")
n = last - first + 1
print(f"| all | placed {tot['placed']}/{n} | wrong **{tot['gw']}** | {tot['wrong'][0]} → {tot['wrong'][1]} | "
      f"{tot['coll'][0]} → {tot['coll'][1]} | | | | |")
PY
python3 -c 'import sys; sys.path.insert(0, "scripts"); from bench_section import write_section; write_section("BENCHMARKS.md", "mission-grid", sys.stdin.read())' < "$dir/section.md"
cat "$dir/section.md"
