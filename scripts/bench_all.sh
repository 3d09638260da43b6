#!/usr/bin/env bash
# Regenerate every section of BENCHMARKS.md, one script per section, in order. Each script
# rewrites only its own section (between its `<!-- name:begin/end -->` markers) and records
# its command, date, machine and commit there.
#
#   scripts/bench_all.sh [--quick] [--only NAME[,NAME...]] [--list]
#   --quick  fewer seeds, runs and repeats in every script that has a quick mode (about 30
#            minutes on 2 cores instead of several hours); the sections then say so
#   --only   run only the named sections (see --list)
# Environment: SEGLOC_DATA (default ../shared/data), CARGO_TARGET_DIR; peers (GTSAM,
# KISS-Matcher) are installed from PyPI into virtual environments under target/.
set -euo pipefail
cd "$(dirname "$0")/.."
quick=0 only="" list=0
while [[ $# -gt 0 ]]; do
  case "$1" in
    --quick) quick=1; shift ;;
    --only) only="$2"; shift 2 ;;
    --list) list=1; shift ;;
    *) echo "usage: $0 [--quick] [--only NAME[,NAME...]] [--list]" >&2; exit 2 ;;
  esac
done
q() { [[ $quick == 1 ]] && echo "$1" || echo "${2:-}"; }
# name | command (the quick variant from q)
sections=(
  "association|scripts/bench_association.sh $(q --quick)"
  "relocalization|scripts/bench_relocalization.sh"
  "tilt|scripts/bench_tilt.sh $(q --no-mission)"
  "grid|env TRIALS=$(q 2 20) scripts/bench_grid.sh"
  "localizer|scripts/bench_localizer.sh $(q --quick)"
  "stream|scripts/bench_stream.sh $(q --quick)"
  "posegraph|scripts/bench_posegraph.sh --runs $(q 3 11)"
  "stereo-ba|scripts/bench_stereo_ba.sh --runs $(q 3 11)"
  "vo|scripts/bench_vo.sh --runs $(q 1 3)"
  "vo-rendered|scripts/bench_vo_rendered.sh $(q --quick)"
  "localize-images|scripts/bench_localize_images.sh $(q '1 1 60')"
  "merge|scripts/bench_merge.sh"
  "python|scripts/bench_python.sh $(q '--rounds 1 --repeat 5' '--rounds 5 --repeat 20')"
  "mapping|scripts/bench_mapping.sh"
  "perception|scripts/bench_perception.sh $(q --quick)"
  "segmenter|scripts/bench_segmenter.sh"
  "render|scripts/bench_render.sh $(q 11)"
  "render-eval|scripts/bench_render_eval.sh"
  "sim|scripts/bench_sim.sh $(q --quick)"
  "mission|scripts/bench_mission.sh $(q --quick)"
  "mission-rendered|scripts/bench_mission_rendered.sh $(q --quick)"
  "mission-grid|scripts/bench_mission_grid.sh $(q '1 3' '1 10')"
  "fuzz|scripts/fuzz.sh --write --cases $(q 2000 20000)"
)
if [[ $list == 1 ]]; then
  printf '%s\n' "${sections[@]}" | sed 's/|/\t/'
  exit 0
fi
cargo build --release --quiet --bin segloc --examples
failed=()
for entry in "${sections[@]}"; do
  name="${entry%%|*}" cmd="${entry#*|}"
  if [[ -n "$only" && ",$only," != *",$name,"* ]]; then continue; fi
  echo "== $name: $cmd" >&2
  started=$(date +%s)
  if ! $cmd >&2; then failed+=("$name"); fi
  echo "== $name: $(( $(date +%s) - started )) s" >&2
done
if [[ ${#failed[@]} -gt 0 ]]; then
  echo "bench_all: failed: ${failed[*]} (their sections were left as they were)" >&2
  exit 1
fi
