#!/usr/bin/env bash
# Longer runs of the parser fuzz layer (issue 25 §3): every reader under mutation.
#
#   scripts/fuzz.sh [--cases N] [--seed S]
#
# CI runs 2,000 cases per parser with a fixed seed (`cargo test --release`); this runs N
# (default 50,000) per parser, with seed S when given (another seed explores other cases).
# The tests read SEGLOC_FUZZ_CASES and SEGLOC_FUZZ_SEED.
set -euo pipefail
cd "$(dirname "$0")/.."

cases=50000
seed=""
while [ $# -gt 0 ]; do
    case "$1" in
        --cases) cases="$2"; shift 2 ;;
        --seed) seed="$2"; shift 2 ;;
        -h|--help) sed -n '2,9p' "$0"; exit 0 ;;
        *) echo "fuzz.sh: unknown argument '$1' (try --help)" >&2; exit 2 ;;
    esac
done
case "$cases" in
    ''|*[!0-9]*) echo "fuzz.sh: --cases needs a positive number, got '$cases'" >&2; exit 2 ;;
esac

export SEGLOC_FUZZ_CASES="$cases"
if [ -n "$seed" ]; then
    export SEGLOC_FUZZ_SEED="$seed"
fi
export RUST_BACKTRACE=0
echo "fuzz: $cases cases per parser${seed:+, seed $seed}"
cargo test --release -p segloc-maps --test fuzz -- --nocapture --test-threads 1
cargo test --release -p segloc --test fuzz_parsers -- --nocapture --test-threads 1
