#!/usr/bin/env bash
# BENCHMARKS.md, "Python bindings": a paper-pair relocalization from Python against the same
# call in Rust (median of REPEAT calls per pair; ROUNDS alternating rounds of both, so that
# the load of a shared machine falls on both alike), and the wheel's size. With
# --clean-build also the wheel's build time from a clean clone of HEAD (fresh target dir).
#
#   scripts/bench_python.sh [--clean-build] [--repeat 20] [--rounds 3]
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)
target="${CARGO_TARGET_DIR:-$repo/target}"
venv="$target/python-venv"
repeat=20 rounds=3 clean=0
while [ $# -gt 0 ]; do
  case "$1" in
    --clean-build) clean=1 ;;
    --repeat) repeat=$2; shift ;;
    --rounds) rounds=$2; shift ;;
    *) echo "usage: $0 [--clean-build] [--repeat N] [--rounds N]" >&2; exit 2 ;;
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
  echo "clean_build_s $(( $(date +%s) - started ))"
  rm -rf "$scratch"
fi
rm -rf "$target/wheels"
"$venv/bin/maturin" build --release --quiet -m python/Cargo.toml -o "$target/wheels"
wheel=$(ls "$target"/wheels/segloc-*.whl)
echo "wheel_bytes $(stat -c %s "$wheel") $(basename "$wheel")"
"$venv/bin/pip" install -q --force-reinstall --no-deps "$wheel"
cargo build --release --quiet --example relocalize_pairs_timing

out=$(mktemp)
for round in $(seq "$rounds"); do
  "$target/release/examples/relocalize_pairs_timing" "$repeat" | sed "s/^/rust $round /" >> "$out"
  (cd /tmp && "$venv/bin/python" "$repo/python/examples/relocalize_pairs.py" --repeat "$repeat" --json) \
    | sed "s/^/python $round /" >> "$out"
done
python3 - "$out" <<'PY'
import json, statistics, sys
runs = {}
for line in open(sys.argv[1]):
    side, rnd, rest = line.split(" ", 2)
    r = json.loads(rest)
    runs.setdefault((side, tuple(r["pair"])), []).append(r["median_ms"])
pairs = sorted({p for _, p in runs})
ratios = []
for p in pairs:
    rust, py = statistics.median(runs[("rust", p)]), statistics.median(runs[("python", p)])
    ratios.append(py / rust)
    print(f"pair {p[0]}-{p[1]}: rust {rust:.3f} ms, python {py:.3f} ms, python/rust {py / rust:.3f}")
total_rust = sum(statistics.median(runs[("rust", p)]) for p in pairs)
total_py = sum(statistics.median(runs[("python", p)]) for p in pairs)
print(f"all pairs: rust {total_rust:.3f} ms, python {total_py:.3f} ms, overhead {100 * (total_py / total_rust - 1):+.1f} %")
PY
rm -f "$out"
