#!/usr/bin/env bash
# Stereo visual odometry on rendered drives of the synthetic moon (issue 27): for each seed,
# `segloc sim render --seed S --seconds T --every 2` (10 Hz, 1280 × 720) and
# `segloc eval vo --images DIR` against the render's truth: KITTI's drift over 10 m
# segments, the end-point error, lost frames and time. Writes the section "vo-rendered" of
# BENCHMARKS.md. Seeds 1-10 were never used to tune the VO (its defaults come from the
# KITTI frames and from seeds 11-13 of the synthetic moon).
#
# Usage: scripts/bench_vo_rendered.sh [--quick] [--print] [--runs DIR] [--low-sun SEED|none]
#                                     [--threads N] [--before DIR] [FIRST LAST [SECONDS]]
#   defaults: seeds 1-10, 300 s, sun elevation 15° and a 5° run of the first seed (--low-sun);
#   quick: seed 1, 20 s; threads: RAYON_NUM_THREADS of the odometry (default 2). Each seed's JSON is kept in --runs DIR (default
#   target/bench-vo-rendered) and reused when present, so a long run can be resumed.
#   before: a --runs DIR of another binary on the same drives (same file names): its
#   rotation drift and lost frames are shown beside this run's.
set -euo pipefail
cd "$(dirname "$0")/.."
first=1 last=10 seconds=300 print=0 runs="" low_sun="" threads=2 before="" args=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --quick) last=1 seconds=20 ;;
    --print) print=1 ;;
    --runs) runs="$2"; shift ;;
    --low-sun) low_sun="$2"; shift ;;
    --threads) threads="$2"; shift ;;
    --before) before="$2"; shift ;;
    *) args+=("$1") ;;
  esac
  shift
done
[[ ${#args[@]} -ge 2 ]] && first=${args[0]} last=${args[1]}
[[ ${#args[@]} -ge 3 ]] && seconds=${args[2]}
source scripts/bench_lib.sh
segloc_bin
runs="${runs:-$target/bench-vo-rendered}"
mkdir -p "$runs"
one() {  # seed sun_elevation
  local out="$runs/vo-s$1-e$2-t$seconds-j$threads.json"
  [[ -s "$out" ]] && return
  local dir="$runs/render-s$1"
  rm -rf "$dir"
  "$bin" sim render --seed "$1" --seconds "$seconds" --every 2 --sun-elevation "$2" -o "$dir" > /dev/null
  RAYON_NUM_THREADS=$threads "$bin" eval vo --images "$dir" --per-frame "${out%.json}.csv" --json > "$out.tmp"
  # why each lost frame was lost, while the images are still there (needs numpy and Pillow)
  if "${PYTHON:-python3}" -c 'import numpy, PIL' 2> /dev/null; then
    "${PYTHON:-python3}" scripts/vo_lost_frames.py "$dir" "${out%.json}.csv" > "${out%.json}.lost.txt"
  fi
  mv "$out.tmp" "$out"
  rm -rf "$dir"
}
for s in $(seq "$first" "$last"); do one "$s" 15; done
low_sun="${low_sun:-$first}"
[[ $low_sun != none ]] && one "$low_sun" 5
section=$(python3 - "$runs" "$first" "$last" "$seconds" "$low_sun" "$threads" "$before" <<'PY'
import json, sys, datetime, subprocess, os
d, first, last, seconds, low_sun, threads, before = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4], sys.argv[5], sys.argv[6], sys.argv[7]
sh = lambda c: subprocess.run(["sh", "-c", c], capture_output=True, text=True).stdout.strip()
commit = sh("git rev-parse --short HEAD")
date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
def earlier(s, e):
    path = f"{before}/vo-s{s}-e{e}-t{seconds}-j{threads}.json"
    return json.load(open(path)) if before and os.path.exists(path) else None
def row(s, e):
    v = json.load(open(f"{d}/vo-s{s}-e{e}-t{seconds}-j{threads}.json"))
    b = earlier(s, e)
    g = v.get("drift_10m") or {}
    was = lambda x: f"{x} → " if b else ""
    rot_before = was(f"{b['drift_10m']['rotation_deg_per_10m']:.3f}°" if b and b.get("drift_10m") else "—")
    drift = (f"{g['translation_percent']:.2f} % / {g['translation_percent_p90']:.2f} % | {rot_before}**{g['rotation_deg_per_10m']:.3f}°**"
             if g else "— | —")
    return v, (f"| {s} | {e}° | {v['distance_m']:.1f} | {drift} | {v['translation_error_percent']:.2f} % "
               f"| {was(b['lost_frames']) if b else ''}{v['lost_frames']}/{v['frames']} | {v['tracked_features']:.0f} | {v['per_frame_ms']['median']:.0f} / {v['per_frame_ms']['p99']:.0f} |")
runs = [row(s, 15) for s in range(first, last + 1)]
main = [v for v, _ in runs]
if low_sun != "none":
    runs.append(row(int(low_sun), 5))
def med(xs):
    xs = sorted(xs); return xs[len(xs) // 2] if len(xs) % 2 else 0.5 * (xs[len(xs) // 2 - 1] + xs[len(xs) // 2])
def p90(xs):
    xs = sorted(xs); return xs[round((len(xs) - 1) * 0.9)]
tr = [v["drift_10m"]["translation_percent"] for v in main if v.get("drift_10m")]
ro = [v["drift_10m"]["rotation_deg_per_10m"] for v in main if v.get("drift_10m")]
ms = [v["per_frame_ms"]["median"] for v in main]
old = [earlier(s, 15) for s in range(first, last + 1)]
old_ro = [v["drift_10m"]["rotation_deg_per_10m"] for v in old if v and v.get("drift_10m")]
summary = (f"Over seeds {first}–{last} at 15°: translation drift median {med(tr):.2f} %, p90 {p90(tr):.2f} %; rotation median "
           f"{med(ro):.3f}° per 10 m, p90 {p90(ro):.3f}°; lost frames {sum(v['lost_frames'] for v in main)} of "
           f"{sum(v['frames'] for v in main)}; time median of the seeds' medians {med(ms):.0f} ms a frame." if tr else "")
if old_ro and len(old_ro) == len(ro):
    summary += (f" Before (`--before`): rotation median {med(old_ro):.3f}°, p90 {p90(old_ro):.3f}°; "
                f"translation median {med([v['drift_10m']['translation_percent'] for v in old]):.2f} %.")
causes = {}
for s in range(first, last + 1):
    path = f"{d}/vo-s{s}-e15-t{seconds}-j{threads}.lost.txt"
    for line in open(path) if os.path.exists(path) else []:
        if line.startswith("counts:"):
            for item in filter(None, line[len("counts:"):].split(",")):
                name, n = item.strip().rsplit(" ", 1)
                causes[name] = causes.get(name, 0) + int(n)
if causes:
    summary += (" Lost frames by what the left image held (`scripts/vo_lost_frames.py`): "
                + ", ".join(f"{k} {v}" for k, v in sorted(causes.items())) + ".")
stages = main[0].get("stage_ms_median") or {}
stages = "Median ms per stage (seeds' medians): " + ", ".join(
    f"{k[:-3]} {med([v['stage_ms_median'][k] for v in main]):.1f}" for k in stages) if stages else ""
print("\n".join([
    "## Stereo visual odometry on rendered drives (issue 27)", "",
    f"`scripts/bench_vo_rendered.sh {first} {last} {seconds}` — {date}, commit `{commit}`, AMD EPYC, 2 cores shared "
    f"(load average {os.getloadavg()[0]:.1f}); `segloc sim render --seed S --seconds {seconds} --every 2 --sun-elevation E` "
    f"(10 Hz, 1280 × 720) then `RAYON_NUM_THREADS={threads} segloc eval vo --images DIR`, default `VoConfig`. Held out: seeds 1–10 "
    "(tuned on KITTI and seeds 11–13). Drift: KITTI's metric over 10 m segments, mean / p90 over the segments.", "",
    f"| seed | sun | distance (m) | translation drift mean / p90 | rotation per 10 m{', before → now' if before else ''} | end point | lost{', before → now' if before else ''} | tracked (median) | ms a frame median / p99 |",
    "|---|---|---|---|---|---|---|---|---|",
    *[r for _, r in runs], "",
    " ".join(x for x in [summary, stages + "." if stages else "",
             "Targets: ≤ 1 % over 10 m (median over seeds), ≤ 0.1° per 10 m, no frame lost, ≤ 40 ms a frame on 2 cores."] if x),
]))
PY
)
if [[ $print == 1 ]]; then
  echo "$section"
else
  python3 -c 'import sys; sys.path.insert(0, "scripts"); from bench_section import write_section; write_section("BENCHMARKS.md", "vo-rendered", sys.stdin.read())' <<< "$section"
  echo "$section"
fi
