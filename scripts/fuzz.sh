#!/usr/bin/env bash
# Longer runs of the parser fuzz layer (issue 25 §3): every reader under mutation.
#
#   scripts/fuzz.sh [--cases N] [--seed S] [--write]   (--write: the section "fuzz" of BENCHMARKS.md)
#
# CI runs 2,000 cases per parser with a fixed seed (`cargo test --release`); this runs N
# (default 50,000) per parser, with seed S when given (another seed explores other cases).
# The tests read SEGLOC_FUZZ_CASES and SEGLOC_FUZZ_SEED.
set -euo pipefail
cd "$(dirname "$0")/.."

cases=50000
seed=""
write=0
while [ $# -gt 0 ]; do
    case "$1" in
        --cases) cases="$2"; shift 2 ;;
        --seed) seed="$2"; shift 2 ;;
        --write) write=1; shift ;;
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
cargo test --release --quiet -p segloc-maps --test fuzz --no-run
cargo test --release --quiet -p segloc --test fuzz_parsers --no-run
t0=$(date +%s.%N)
cargo test --release -p segloc-maps --test fuzz -- --nocapture --test-threads 1
t1=$(date +%s.%N)
cargo test --release -p segloc --test fuzz_parsers -- --nocapture --test-threads 1
t2=$(date +%s.%N)
[ "$write" = 1 ] || exit 0
maps_s=$(python3 -c "print(f'{$t1 - $t0:.1f}')")
engine_s=$(python3 -c "print(f'{$t2 - $t1:.1f}')")
cpu=$(lscpu | sed -n 's/^Model name: *//p' | head -1)
python3 scripts/bench_section.py fuzz <<EOF
## Every reader under mutation (\`scripts/fuzz.sh\`)

\`scripts/fuzz.sh --cases $cases --write\`${seed:+ (seed $seed)} — $(date -u +%Y-%m-%d), $cpu, commit \`$(git rev-parse --short HEAD)\`; CI runs the same two test targets with 2,000 cases per reader. Each reader gets fixed-seed proptest cases: 80 % mutations of a small valid file (truncation, byte flips, huge / negative / \`NaN\` / \`1e999\` tokens, duplicated and deleted lines, a 200 KB line, non-UTF-8 bytes), 20 % random bytes or text. Property: a typed error or a valid value, no panic, each case under 500 ms, no single allocation over 256 KiB + 64 × the input (1 MiB + 1100 × for the compressed \`.lac\`).

| readers | cases each | time, one thread |
|---|---|---|
| maps: map JSON, detections CSV, traverse CSV, grid CSV, frames JSONL, TUM, point list, non-UTF-8 paths | $cases | $maps_s s |
| engine: g2o, TORO, \`.lac\` (compressed and inner tar), association problem and ground truth, relocalize / localizer / mission TOML | $cases | $engine_s s |

Found and fixed so far, each with a regression test beside its parser: allocations sized by a count in the input (traverse rows, association problems, \`.lac\` tar headers: up to 24 TB requested), a \`.lac\` member shorter than its header, the grid CSV's fixed 1.8 MB reservation.
EOF
