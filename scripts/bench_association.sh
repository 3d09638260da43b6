#!/usr/bin/env bash
# Association benchmark: segloc's consistency graph + densest clique against KISS-Matcher on
# generated problems, plus end-to-end relocalization on the five LunarLoc paper pairs.
# Writes the section of BENCHMARKS.md between <!-- association:begin --> and
# <!-- association:end --> (nothing else in the file is touched).
#
#   scripts/bench_association.sh [--quick]      (from anywhere; works from the repo root)
#
#   --quick   one seed per problem kind instead of five
# Environment:
#   SEGLOC_SHARED  shared folder with bench/ (default ../shared, relative to the repo root)
#   SEGLOC_DATA    data folder with lunarloc/ (default ../shared/data, relative to the repo root)
# Needs: cargo, python3 with the venv module; PyPI for numpy + kiss-matcher (optional: without
# them the peer columns say "not run"). Scratch files go to target/bench/, the venv to
# target/bench-venv/.
set -euo pipefail

usage() { sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//'; }

seeds=5
for arg in "$@"; do
    case "$arg" in
        --quick) seeds=1 ;;
        -h | --help) usage; exit 0 ;;
        *) echo "bench_association.sh: unknown argument '$arg'" >&2; usage >&2; exit 2 ;;
    esac
done

say() { printf '[bench_association] %s\n' "$*" >&2; }
die() { say "error: $*"; exit 1; }

repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo_root"

shared="${SEGLOC_SHARED:-../shared}"
data="${SEGLOC_DATA:-../shared/data}"
gen="$shared/bench/gen_association_problem.py"
peer="$shared/bench/kiss_peer.py"
helper="scripts/bench_association.py"

command -v python3 >/dev/null || die "python3 not found"
command -v cargo >/dev/null || die "cargo not found"
[[ -f "$gen" ]] || die "problem generator not found at $gen (set SEGLOC_SHARED)"
[[ -f "$peer" ]] || die "KISS-Matcher peer script not found at $peer (set SEGLOC_SHARED)"
for n in 3 5 7 12; do
    [[ -f "$data/lunarloc/traverse_$n.csv" ]] ||
        die "LunarLoc traverse $n not found at $data/lunarloc/ (set SEGLOC_DATA)"
done

# 1. build (the tree is shared with people editing it: retry a few times if it is broken)
for attempt in 1 2 3 4 5; do
    say "cargo build --release (attempt $attempt)"
    if cargo build --release; then
        built=1
        break
    fi
    built=0
    if [[ $attempt -lt 5 ]]; then
        say "build failed; retrying in 60 s"
        sleep 60
    fi
done
[[ "${built:-0}" == 1 ]] || die "cargo build --release failed 5 times"
segloc="target/release/segloc"
[[ -x "$segloc" ]] || die "$segloc missing after the build"

# 2. the peer's Python environment
venv="target/bench-venv"
peer_python=""
no_kiss_reason=""
if [[ ! -x "$venv/bin/python" ]]; then
    say "creating $venv"
    python3 -m venv "$venv" || no_kiss_reason="could not create a Python venv (python3 -m venv failed)"
fi
if [[ -z "$no_kiss_reason" ]]; then
    if "$venv/bin/python" -c 'import numpy, kiss_matcher' 2>/dev/null; then
        peer_python="$venv/bin/python"
    else
        say "pip install numpy kiss-matcher into $venv"
        if "$venv/bin/python" -m pip install --quiet numpy kiss-matcher &&
            "$venv/bin/python" -c 'import numpy, kiss_matcher'; then
            peer_python="$venv/bin/python"
        else
            no_kiss_reason="pip install kiss-matcher failed"
        fi
    fi
fi
if [[ -n "$no_kiss_reason" ]]; then
    say "continuing without KISS-Matcher: $no_kiss_reason"
fi

# 3-5. problems, segloc and peer runs, end-to-end relocalization
mkdir -p target/bench
results="target/bench/association-results.json"
status=0
python3 "$helper" run \
    --segloc "$segloc" --shared "$shared" --data "$data" --bench-dir target/bench \
    --seeds "$seeds" --peer-python "$peer_python" --no-kiss-reason "$no_kiss_reason" \
    --out "$results" || status=$?
[[ -f "$results" ]] || die "no results written (see the messages above)"

# 6. the markdown section
cmd="scripts/bench_association.sh${*:+ $*}"
python3 "$helper" report --results "$results" --markdown BENCHMARKS.md --command "$cmd"
if [[ $status -ne 0 ]]; then
    say "some runs failed; they are listed in BENCHMARKS.md"
fi
exit "$status"
