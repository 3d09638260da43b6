#!/usr/bin/env bash
# The localizer from pixels (issue 27's `segloc localize --images`): for each seed, session 2
# of the mission rendered at 10 Hz and 1280 × 720 (`segloc sim render --session 2`), its
# prior (session 1's map, `segloc sim export --prior-map`), then `segloc localize --images`
# (stereo VO + the perception front end at 1 Hz + the online localizer) against that prior.
# Scores `prior_from_rover` against the render's truth: after the first fix (the written
# trajectory) and, with `--all-frames`, every frame as the final solve places it. Writes the
# section "localize-images" of BENCHMARKS.md. Seeds 1-3 were not used to tune anything.
#
# Usage: scripts/bench_localize_images.sh [--print] [--runs DIR] [FIRST LAST [SECONDS]]
#   defaults: seeds 1-3, 120 s. Each seed's results are kept in --runs DIR (default
#   target/bench-localize-images) and reused when present.
set -euo pipefail
cd "$(dirname "$0")/.."
first=1 last=3 seconds=120 print=0 runs="" args=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --print) print=1 ;;
    --runs) runs="$2"; shift ;;
    *) args+=("$1") ;;
  esac
  shift
done
[[ ${#args[@]} -ge 2 ]] && first=${args[0]} last=${args[1]}
[[ ${#args[@]} -ge 3 ]] && seconds=${args[2]}
source scripts/bench_lib.sh
segloc_bin
runs="${runs:-$target/bench-localize-images}"
mkdir -p "$runs"
for s in $(seq "$first" "$last"); do
  out="$runs/s$s-t$seconds"
  [[ -s "$out.json" ]] && continue
  rm -rf "$out.render"
  "$bin" sim render --seed "$s" --session 2 --seconds "$seconds" --every 2 -o "$out.render" > /dev/null
  "$bin" sim export --seed "$s" --session 2 --seconds 1 -o "$out.unused.jsonl" --prior-map "$out.prior.json" > /dev/null
  cp "$out.render/truth.tum" "$out.truth.tum"
  code=0
  "$bin" localize --prior "$out.prior.json" --images "$out.render" -o "$out.tum" \
    --frames-out "$out.frames.jsonl" --json > "$out.json.tmp" || code=$?
  [[ $code -le 1 ]] || exit "$code"
  "$bin" localize --prior "$out.prior.json" --frames "$out.frames.jsonl" -o "$out.all.tum" --all-frames > /dev/null || true
  mv "$out.json.tmp" "$out.json"
  rm -rf "$out.render" "$out.unused.jsonl"
done
section=$(python3 - "$runs" "$first" "$last" "$seconds" <<'PY'
import json, sys, math, datetime, subprocess, os
d, first, last, seconds = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
sh = lambda c: subprocess.run(["sh", "-c", c], capture_output=True, text=True).stdout.strip()
def qmul(a, b):
    (x1, y1, z1, w1), (x2, y2, z2, w2) = a, b
    return (w1*x2 + x1*w2 + y1*z2 - z1*y2, w1*y2 - x1*z2 + y1*w2 + z1*x2, w1*z2 + x1*y2 - y1*x2 + z1*w2, w1*w2 - x1*x2 - y1*y2 - z1*z2)
def rot(q, v):
    x, y, z, w = qmul(qmul(q, (v[0], v[1], v[2], 0.0)), (-q[0], -q[1], -q[2], q[3]))
    return (x, y, z)
def tum(path):
    out = {}
    if not os.path.exists(path):
        return out
    for line in open(path):
        if line.startswith("#") or not line.strip():
            continue
        v = [float(x) for x in line.split()]
        out[round(v[0], 3)] = (v[1:4], v[4:8])
    return out
# the rover's origin from the left camera's pose: p_rover_origin = p_cam + R_cam · (camera_from_rover translation)
C_FROM_R = (0.081, 0.131, -0.28)  # rover origin in the optical frame (x right, y down, z forward)
def rover_positions(truth):
    return {t: tuple(p[i] + rot(q, C_FROM_R)[i] for i in range(3)) for t, (p, q) in truth.items()}
def rmse(est, truth):
    e = [math.dist(p, truth[t]) for t, (p, _) in est.items() if t in truth]
    return (math.sqrt(sum(x * x for x in e) / len(e)), max(e)) if e else (float("nan"), float("nan"))
def cm(x):
    return "—" if math.isnan(x) else f"{100 * x:.1f}"
rows = []
for s in range(first, last + 1):
    base = f"{d}/s{s}-t{seconds}"
    v = json.load(open(base + ".json"))
    truth = rover_positions(tum(base + ".truth.tum"))
    after, after_max = rmse(tum(base + ".tum"), truth)
    every, every_max = rmse(tum(base + ".all.tum"), truth)
    im = v["image_stream"]
    fix = v["first_fix_t"]
    rows.append(f"| {s} | {v['frames']} | {im['vo_lost_frames']} | {im['detections'] / max(im['detection_frames'], 1):.1f} "
                f"| {v['fixes']['accepted']} / {v['fixes']['refused']} | {'—' if fix is None else f'{fix:.0f} s'} "
                f"| {cm(after)} / {cm(after_max)} | {cm(every)} | {im['vo_ms']['median']:.0f} | {im['front_end_ms']['median']:.0f} |")
commit = sh("git rev-parse --short HEAD")
date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
print("\n".join([
    "## The localizer from pixels (`segloc localize --images`)", "",
    f"`scripts/bench_localize_images.sh {first} {last} {seconds}` — {date}, commit `{commit}`, AMD EPYC, 2 cores shared "
    f"(load average {os.getloadavg()[0]:.1f}). Session 2 of seed S, {seconds} s rendered at 10 Hz, 1280 × 720, against session 1's map "
    "(`sim export --prior-map`): stereo VO on every pair, the geometric front end once a second, the online localizer. "
    "Error: the rover's position against the render's truth, cm. Held out: seeds 1–3 (nothing tuned on them).", "",
    "| seed | pairs | VO lost | boulders a detection pair | fixes accepted / refused | first fix | RMSE / max after the first fix | RMSE every frame (final solve) | VO ms median | front end ms median |",
    "|---|---|---|---|---|---|---|---|---|---|",
    *rows, "",
    "Target (issue 27, the mission on images): session-2 RMSE ≤ 2 cm, no wrong accepted fix.",
]))
PY
)
if [[ $print == 1 ]]; then
  echo "$section"
else
  python3 -c 'import sys; sys.path.insert(0, "scripts"); from bench_section import write_section; write_section("BENCHMARKS.md", "localize-images", sys.stdin.read())' <<< "$section"
  echo "$section"
fi
