#!/usr/bin/env bash
# Stereo visual odometry on rendered drives of the synthetic moon (issue 27): for each seed,
# `segloc sim render --seed S --seconds T --every 2` (10 Hz, 1280 × 720, the default sun) and
# `segloc eval vo --images DIR` against the render's truth. Writes the section "vo-rendered"
# of BENCHMARKS.md. Seeds of the synthetic moon were never used to tune the VO (its defaults
# come from the KITTI frames).
#
# Usage: scripts/bench_vo_rendered.sh [--quick] [--print] [FIRST LAST [SECONDS]]
#   (defaults: seeds 1-3, 60 s; quick: seed 1, 20 s)
set -euo pipefail
cd "$(dirname "$0")/.."
first=1 last=3 seconds=60 print=0 args=()
for a in "$@"; do
  case "$a" in
    --quick) last=1 seconds=20 ;;
    --print) print=1 ;;
    *) args+=("$a") ;;
  esac
done
[[ ${#args[@]} -ge 2 ]] && first=${args[0]} last=${args[1]}
[[ ${#args[@]} -ge 3 ]] && seconds=${args[2]}
source scripts/bench_lib.sh
segloc_bin
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
for s in $(seq "$first" "$last"); do
  "$bin" sim render --seed "$s" --seconds "$seconds" --every 2 -o "$work/r$s" > /dev/null
  RAYON_NUM_THREADS=1 "$bin" eval vo --images "$work/r$s" --json > "$work/vo$s.json"
  rm -rf "$work/r$s"
done
section=$(python3 - "$work" "$first" "$last" "$seconds" <<'PY'
import json, sys, datetime, subprocess, os
d, first, last, seconds = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
sh = lambda c: subprocess.run(["sh", "-c", c], capture_output=True, text=True).stdout.strip()
commit = sh("git rev-parse --short HEAD")
date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
rows = []
for s in range(first, last + 1):
    v = json.load(open(f"{d}/vo{s}.json"))
    rows.append(f"| {s} | {v['frames']} | {v['distance_m']:.2f} | {v['translation_error_m']:.3f} m ({v['translation_error_percent']:.1f} %) "
                f"| {v['rotation_error_deg']:.2f}° | {v['lost_frames']} | {v['tracked_features']:.0f} | {v['inliers']:.0f} "
                f"| {v['per_frame_ms']['median']:.0f} / {v['per_frame_ms']['p99']:.0f} |")
print("\n".join([
    "## Stereo visual odometry on rendered drives (issue 27)", "",
    f"`scripts/bench_vo_rendered.sh {first} {last} {seconds}` — {date}, commit `{commit}`, AMD EPYC, 2 cores shared "
    f"(load average {os.getloadavg()[0]:.1f}); `segloc sim render --seed S --seconds {seconds} --every 2` (10 Hz, 1280 × 720, "
    "default sun) then `segloc eval vo --images DIR`, one thread, default `VoConfig` (tuned on KITTI only; these seeds are held out).", "",
    "| seed | frames | distance (m) | end-point error | rotation error | lost frames | tracked (median) | inliers (median) | ms a frame median / p99 |",
    "|---|---|---|---|---|---|---|---|---|",
    *rows, "",
    "Targets (issue 27, 300 s drives): ≤ 1 % of distance over 10 m, ≤ 0.1° per 10 m, no frame lost, ≤ 40 ms a frame — **not met**: "
    "the odometry loses track on many frames (the near regolith is smooth, rocks and pebbles give most corners) and the "
    "rotation then drifts; why each loss happens is not yet analysed.",
]))
PY
)
if [[ $print == 1 ]]; then
  echo "$section"
else
  python3 -c 'import sys; sys.path.insert(0, "scripts"); from bench_section import write_section; write_section("BENCHMARKS.md", "vo-rendered", sys.stdin.read())' <<< "$section"
  echo "$section"
fi
