#!/usr/bin/env bash
# BENCHMARKS.md, "Python bindings": a paper-pair relocalization from Python against the same
# call in Rust (median of REPEAT calls per pair; ROUNDS alternating rounds of both, so that
# the load of a shared machine falls on both alike), and the wheel's size. With
# --clean-build also the wheel's build time from a clean clone of HEAD (fresh target dir).
#
#   scripts/bench_python.sh [--clean-build] [--repeat 20] [--rounds 3] [--print]
# Writes the section "python" of BENCHMARKS.md (--print: prints it instead).
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)
target="${CARGO_TARGET_DIR:-$repo/target}"
venv="$target/python-venv"
repeat=20 rounds=3 clean=0
while [ $# -gt 0 ]; do
  case "$1" in
    --clean-build) clean=1 ;;
    --print) print=1 ;;
    --repeat) repeat=$2; shift ;;
    --rounds) rounds=$2; shift ;;
    *) echo "usage: $0 [--clean-build] [--repeat N] [--rounds N] [--print]" >&2; exit 2 ;;
  esac
  shift
done
export SEGLOC_DATA="${SEGLOC_DATA:-$repo/../shared/data}"

[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
"$venv/bin/pip" install -q -r python/requirements-dev.txt
if [ "$clean" = 1 ]; then
  scratch=$(mktemp -d)
  git clone -q "$repo" "$scratch/segloc"
  started=$(date +%s)
  CARGO_TARGET_DIR="$scratch/target" "$venv/bin/maturin" build --release --quiet \
    -m "$scratch/segloc/python/Cargo.toml" -o "$scratch/wheels"
  clean_s=$(( $(date +%s) - started ))
  echo "clean_build_s $clean_s"
  rm -rf "$scratch"
fi
rm -rf "$target/wheels"
"$venv/bin/maturin" build --release --quiet -m python/Cargo.toml -o "$target/wheels"
wheel=$(ls "$target"/wheels/segloc-*.whl)
wheel_bytes=$(stat -c %s "$wheel")
echo "wheel_bytes $wheel_bytes $(basename "$wheel")"
"$venv/bin/pip" install -q --force-reinstall --no-deps "$wheel"
cargo build --release --quiet --example relocalize_pairs_timing

out=$(mktemp)
for round in $(seq "$rounds"); do
  "$target/release/examples/relocalize_pairs_timing" "$repeat" | sed "s/^/rust $round /" >> "$out"
  (cd /tmp && "$venv/bin/python" "$repo/python/examples/relocalize_pairs.py" --repeat "$repeat" --json) \
    | sed "s/^/python $round /" >> "$out"
done
section=$(python3 - "$out" "$rounds" "$repeat" "$wheel_bytes" "$(basename "$wheel")" "${clean_s:-}" <<'PY'
import json, statistics, sys, datetime, subprocess
out, rounds, repeat, wheel_bytes, wheel, clean_s = sys.argv[1:7]
runs = {}
for line in open(out):
    side, rnd, rest = line.split(" ", 2)
    r = json.loads(rest)
    runs.setdefault((side, tuple(r["pair"])), []).append(r["median_ms"])
pairs = sorted({p for _, p in runs})
cells = []
for p in pairs:
    rust, py = statistics.median(runs[("rust", p)]), statistics.median(runs[("python", p)])
    cells.append(f"{p[0]}–{p[1]} {rust:.2f} / {py:.2f}")
total_rust = sum(statistics.median(runs[("rust", p)]) for p in pairs)
total_py = sum(statistics.median(runs[("python", p)]) for p in pairs)
sh = lambda c: subprocess.run(["sh", "-c", c], capture_output=True, text=True).stdout.strip()
cpu, commit = sh("lscpu | sed -n 's/Model name: *//p'"), sh("git rev-parse --short HEAD")
overhead = 100 * (total_py / total_rust - 1)
print("## Python bindings (`pip install ./python`)\n")
print(f"`scripts/bench_python.sh --rounds {rounds} --repeat {repeat}` — {datetime.date.today()}, {cpu}, commit `{commit}`. "
      "`python/examples/relocalize_pairs.py` and its Rust twin `examples/relocalize_pairs_timing.rs` relocalize each "
      f"paper pair's query against the prior traverse: median wall time of {repeat} calls after 2 warm-ups, "
      f"{rounds} alternating rounds, median of the rounds; the same answers both sides.\n")
print(f"Rust / Python ms: {', '.join(cells)}; all pairs **{total_rust:.2f} / {total_py:.2f} ({overhead:+.1f} %)** "
      f"(target ≤ 5 % slower: {'met' if overhead <= 5 else '**not met**'}). Wheel: {int(wheel_bytes):,} bytes (`{wheel}`, "
      "abi3: one wheel for CPython ≥ 3.9, stripped)" + (f"; built from a clean clone in {clean_s} s wall." if clean_s else "."))
PY
)
rm -f "$out"
if [ "${print:-0}" = 1 ]; then echo "$section"; else echo "$section" | python3 scripts/bench_section.py python; fi
