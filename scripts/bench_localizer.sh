#!/usr/bin/env bash
# The online localizer's per-frame cost and accuracy on a long recorded drive: session 2 of
# a mission exported as a frames file (seed and length as arguments), localized by
# `segloc localize` against session 1's map, scored against the exported truth.
# Usage: scripts/bench_localizer.sh [--quick] [SEED] [SECONDS]   (defaults: 1 5000; quick: 1 600)
set -euo pipefail
cd "$(dirname "$0")/.."
quick=0
if [[ "${1:-}" == "--quick" ]]; then quick=1; shift; fi
seed="${1:-1}"
seconds="${2:-$([[ $quick == 1 ]] && echo 600 || echo 5000)}"
cargo build --release --bin segloc >/dev/null 2>&1
bin=target/release/segloc
dir="$(mktemp -d)"
trap 'rm -rf "$dir"' EXIT
"$bin" sim export --seed "$seed" --session 2 --seconds "$seconds" \
  -o "$dir/drive.jsonl" --truth "$dir/truth.tum" --prior-map "$dir/prior.map.json" 2>/dev/null
RAYON_NUM_THREADS=1 "$bin" localize --prior "$dir/prior.map.json" --frames "$dir/drive.jsonl" \
  -o "$dir/out.tum" --json > "$dir/summary.json"
python3 - "$dir" "$seed" "$seconds" <<'PY'
import json, math, sys, datetime, subprocess
d, seed, seconds = sys.argv[1], sys.argv[2], sys.argv[3]
def tum(p):
    out = {}
    for line in open(p):
        if line.startswith('#') or not line.strip():
            continue
        v = [float(x) for x in line.split()]
        out[round(v[0], 6)] = v[1:4]
    return out
est, truth = tum(f"{d}/out.tum"), tum(f"{d}/truth.tum")
err = [math.dist(est[t], truth[t]) for t in est]
rmse = math.sqrt(sum(e * e for e in err) / len(err))
s = json.load(open(f"{d}/summary.json"))
cpu = subprocess.run(["sh", "-c", "lscpu | sed -n 's/Model name: *//p'"], capture_output=True, text=True).stdout.strip()
print(f"`scripts/bench_localizer.sh {seed} {seconds}` — {datetime.date.today()}, {cpu}, one thread\n")
print("| frames | fixes accepted / refused | first fix | RMSE from the first fix | per frame (no attempt) median / p99 / max | attempt frames median / p99 |")
print("|---|---|---|---|---|---|")
pf, at = s["per_frame_ms"], s["attempt_ms"]
print(f"| {s['frames']} | {s['fixes']['accepted']} / {s['fixes']['refused']} | {s['first_fix_t']} s | {100*rmse:.2f} cm (max {100*max(err):.2f}) "
      f"| {pf['median']:.4f} / {pf['p99']:.4f} / {pf['max']:.3f} ms | {at['median']:.1f} / {at['p99']:.1f} ms |")
PY
