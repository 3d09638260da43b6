#!/usr/bin/env bash
# Renderer speed and the perception front end on rendered frames against their truth.
# Writes the section "render-eval" of BENCHMARKS.md (PRINT=1: prints it instead).
#
#  1. `segloc bench render` (held-out seeds 11-14, 6 pairs each = 24 stereo pairs at
#     1280 x 720, one renderer per seed): wall and CPU ms a pair, median and p90; with
#     OLD_BIN=<older segloc binary> the same command of the older build runs in the same
#     script, alternating, and the ratio is printed.
#  2. `segloc eval render --seeds 1-10 --sun-deg 5,15,30`: recall, precision and centroid
#     error of `segloc detect`'s front end (geometric segmenter), rocks >= 10 cm within 6 m.
#
# usage: [OLD_BIN=path] [SEGLOC_BIN=path] scripts/bench_render_eval.sh
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-target}"
BIN="${SEGLOC_BIN:-$CARGO_TARGET_DIR/release/segloc}"
[ -n "${SEGLOC_BIN:-}" ] || nice -n 10 cargo build --release -q
TMP="$(mktemp -d)"
trap 'rm -rf "$TMP"' EXIT
for s in 11 12 13 14; do
  "$BIN" bench render --seeds "$s" --pairs 6 --json >"$TMP/new_$s.json"
  if [ -n "${OLD_BIN:-}" ]; then
    "$OLD_BIN" bench render --seeds "$s" --pairs 6 --json >"$TMP/old_$s.json"
  fi
done
"$BIN" eval render --seeds 1-10 --sun-deg 5,15,30 --json >"$TMP/eval.json"
section=$(python3 - "$TMP" <<'PY'
import datetime, glob, json, statistics, subprocess, sys
tmp = sys.argv[1]
def runs(kind):
    return [json.load(open(f)) for f in sorted(glob.glob(f"{tmp}/{kind}_*.json"))]
def pooled(rs, key, stat):
    # medians / p90 of the per-seed runs (6 pairs each), pooled by their median
    return statistics.median(r[key][stat] for r in rs)
new, old = runs("new"), runs("old")
ev = json.load(open(f"{tmp}/eval.json"))
sh = lambda c: subprocess.run(["sh", "-c", c], capture_output=True, text=True).stdout.strip()
print("## Renderer speed and the front end on rendered frames\n")
print(f"`scripts/bench_render_eval.sh` — {datetime.date.today()}, AMD EPYC, 2 cores, commit `{sh('git rev-parse --short HEAD')}`, "
      f"load average {' '.join(new[-1]['load_average'])} (shared machine: wall times are noisy, CPU times less so).\n")
pairs = sum(r["pairs"] for r in new)
line = (f"- Stereo pair 1280 × 720 (`segloc bench render`, held-out seeds 11–14, {pairs} pairs): wall median "
        f"{pooled(new, 'pair_ms', 'median'):.0f} ms, p90 {pooled(new, 'pair_ms', 'p90'):.0f} ms; CPU {pooled(new, 'pair_cpu_ms', 'median'):.0f} ms a pair")
if old:
    r = pooled(old, 'pair_cpu_ms', 'median') / pooled(new, 'pair_cpu_ms', 'median')
    line += (f"; old build in the same run: wall {pooled(old, 'pair_ms', 'median'):.0f} ms, CPU {pooled(old, 'pair_cpu_ms', 'median'):.0f} ms "
             f"(CPU ratio old/new {r:.2f})")
print(line + f". Target ≤ 150 ms: {'met' if pooled(new, 'pair_ms', 'median') <= 150 else '**not met** at this load'}.\n")
print("Front end (`segloc eval render --seeds 1-10 --sun-deg 5,15,30`, geometric segmenter, rocks ≥ 10 cm within 6 m, "
      "seen whole and ≥ 50 % unoccluded; true = centroid within 0.3 × size of the visible centre):\n")
print("| set | rocks | detections | recall | precision | centroid error median / p90 |\n|---|---|---|---|---|---|")
def row(name, s):
    print(f"| {name} | {s['rocks']} | {s['detections']} | {s['recall']:.3f} | {s['precision']:.3f} | "
          f"{100*s['centroid_error_median_m']:.1f} / {100*s['centroid_error_p90_m']:.1f} cm |")
row(f"all ({ev['overall']['frames']} frames)", ev["overall"])
for b in ev["by_range"]:
    row(b["band"], b["summary"])
for b in ev["by_sun"]:
    row(f"sun {b['sun_deg']:g}°", b["summary"])
o = ev["overall"]
met = lambda ok: "met" if ok else "**not met**"
print(f"\nTargets: recall ≥ 0.9 {met(o['recall'] >= 0.9)}, precision ≥ 0.9 {met(o['precision'] >= 0.9)}, "
      f"centroid median ≤ 2 cm {met(o['centroid_error_median_m'] <= 0.02)}. "
      f"Front end {ev['front_end_ms']['median']:.0f} ms median a pair.")
PY
)
if [[ "${PRINT:-0}" == 1 ]]; then echo "$section"; else echo "$section" | python3 scripts/bench_section.py render-eval; fi
