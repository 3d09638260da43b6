#!/usr/bin/env bash
# The online localizer on the real LunarLoc traverses replayed as streams
# (`segloc eval stream`): the paper pairs both ways, then every ordered pair whose maps
# share a boulder. Writes the section "stream" of BENCHMARKS.md (command, date, machine,
# commit, per-pair table of the paper pairs, aggregates of both runs); the JSON reports stay
# in $CARGO_TARGET_DIR/bench (default target/bench).
#
#   scripts/bench_stream.sh [--print] [--quick] [--seed S] [extra `eval stream` options...]
#   --print: print the section instead of writing it; --quick: the paper pairs only
# Environment: SEGLOC_DATA (default ../shared/data, relative to the repo root),
# CARGO_TARGET_DIR, SEGLOC_BIN (a built binary to measure instead of building one).
set -euo pipefail
repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo_root"
source scripts/bench_lib.sh
need_data lunarloc bench_stream
segloc_bin
out="$target/bench"
mkdir -p "$out"
print=0 quick=0 extra=()
for a in "$@"; do
  case "$a" in
    --print) print=1 ;;
    --quick) quick=1 ;;
    *) extra+=("$a") ;;
  esac
done
[[ " ${extra[*]-} " == *" --seed "* ]] || extra+=(--seed 1)

echo "[bench_stream] paper pairs, both ways" >&2
"$bin" eval stream --data "$data" --pairs paper --json "${extra[@]}" > "$out/stream_paper.json"
if [[ $quick == 1 ]]; then
  cp "$out/stream_paper.json" "$out/stream_all.json"
else
  echo "[bench_stream] all ordered pairs sharing a boulder" >&2
  "$bin" eval stream --data "$data" --pairs all --json "${extra[@]}" > "$out/stream_all.json"
fi
echo "[bench_stream] paper pairs, held-out seeds 2 and 3 (default configuration)" >&2
for h in 2 3; do
  "$bin" eval stream --data "$data" --pairs paper --json --seed "$h" > "$out/stream_paper_seed$h.json"
done
echo "[bench_stream] paper pairs, the odometry calibration carried in from the other traverses' drives, seeds 1-8" >&2
for h in 1 2 3 4 5 6 7 8; do
  "$bin" eval stream --data "$data" --pairs paper --json --seed "$h" --carry-calibration others \
    > "$out/stream_paper_carried_seed$h.json"
done

section=$(python3 - "$quick" "$out" "$(date -u '+%Y-%m-%d %H:%M UTC')" \
  "$(lscpu | sed -n 's/^Model name: *//p' | head -1), $(nproc) cores" \
  "$(git rev-parse --short HEAD)" "${extra[*]}" <<'PY'
import json, sys
quick, out, date, machine, commit, extra = sys.argv[1:7]
paper = json.load(open(f"{out}/stream_paper.json"))
every = json.load(open(f"{out}/stream_all.json"))

def cm(x):
    return "–" if x is None else f"{100 * x:.2f}"

def s(x, fmt="{:.0f}"):
    return "–" if x is None else fmt.format(x)

d = paper["drift"]
print("## The online localizer on the real LunarLoc traverses (`segloc eval stream`)")
print()
print(f"Commands: `segloc eval stream --pairs paper --json {extra}` and "
      f"`segloc eval stream --pairs all --json {extra}` (via `scripts/bench_stream.sh`"
      f"{' --quick: paper pairs only' if quick == '1' else ''}). "
      f"Date: {date}. Machine: {machine}. Commit `{commit}`.")
print()
print(f"Odometry: yaw drift {d['yaw_drift_deg_per_10m']}°/10 m, scale error {100 * d['scale_error']:.1f} %, "
      f"yaw random walk {d['yaw_walk_rad_per_sqrt_m']} rad/√m, seed {paper['seed']}; default `LocalizerConfig` "
      "unless the options above say otherwise. RMSE (cm) of positions over the frames from the first fix on: "
      "online (`push_frame`, what the rover knew then), smoothed (`finish`), odometry alone (aligned at the first "
      "frame), *oracle*: every frame that sees the prior map placed exactly and the others carried from there by "
      "the odometry (what a perfect relocalizer without drift calibration would leave); *calibrated oracle*: the same "
      "on the odometry with its deterministic drift (yaw per metre, scale) removed exactly, its random walk kept; "
      "*unseen path*: the distance each frame has driven since it last saw the prior map, rms / max; *seeing prior*: the "
      "online RMSE over those of the frames that see a boulder of the prior map. "
      "A wrong fix: an accepted fix over 10 cm or 1° from the truth of its frame.")
print()
print("| prior | query | frames | fixes / attempts | first fix (s) | online | smoothed | odometry | oracle | calibrated oracle | unseen path (m) | seeing prior (frames) | wrong fixes | frame ms median / p99 | attempt ms median |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for p in paper["pairs"]:
    r, seen, t = p["rmse"], p["rmse_seeing_prior"], p["time"]
    print(f"| {p['prior']} | {p['query']} | {p['frames']} | {p['accepted']} / {p['attempts']} | "
          f"{s(p['time_to_first_fix_s'])} | {cm(r['online_m'])} | {cm(r['smoothed_m'])} | {cm(r['odometry_m'])} | {cm(r['oracle_m'])} | "
          f"{cm(r['calibrated_oracle_m'])} | {p['unseen_path_m']['rms']:.1f} / {p['unseen_path_m']['max']:.1f} | "
          f"{cm(seen['online_m'])} ({seen['frames']}) | {len(p['wrong_fixes'])} | "
          f"{t['median_ms']:.3f} / {t['p99_ms']:.3f} | {t['attempt_median_ms']:.1f} |")
print()
print("| run | pairs (with a fix) | online RMSE median / max | seeing prior median / max | smoothed median / max | fixes | wrong fixes | first fix median (s) |")
print("|---|---|---|---|---|---|---|---|")
runs = (("paper, both ways", paper),) + ((("all sharing a boulder", every),) if quick != "1" else ())
for name, rep in runs:
    a = rep["aggregate"]
    print(f"| {name} | {a['pairs']} ({a['pairs_with_fix']}) | {cm(a['median_rmse_online_m'])} / {cm(a['max_rmse_online_m'])} | "
          f"{cm(a['median_rmse_online_seeing_prior_m'])} / {cm(a['max_rmse_online_seeing_prior_m'])} | "
          f"{cm(a['median_rmse_smoothed_m'])} / {cm(a['max_rmse_smoothed_m'])} | {a['accepted']} | {a['wrong_fixes']} | "
          f"{a['median_time_to_first_fix_s']:.0f} |")
under = [p for p in paper["pairs"] if p["rmse"]["online_m"] is not None and p["rmse"]["online_m"] <= 0.02]
beyond = [f"{p['prior']}→{p['query']}" for p in paper["pairs"]
          if p["rmse"]["oracle_m"] is not None and p["rmse"]["oracle_m"] > 0.02]
cal = [p["rmse"]["calibrated_oracle_m"] for p in paper["pairs"] if p["rmse"]["calibrated_oracle_m"] is not None]
wrong = sum(rep["aggregate"]["wrong_fixes"] for _, rep in runs)
print()
print(f"Targets: no wrong fix over all pairs — {wrong} wrong ({'met' if wrong == 0 else '**not met**'}); online RMSE "
      f"≤ 2 cm on every paper pair — {len(under)} of {len(paper['pairs'])} "
      f"({'met' if len(under) == len(paper['pairs']) else '**not met**'}). Even the oracle leaves over 2 cm on "
      f"{', '.join(beyond) or 'no pair'}: there the query drives far beyond the prior traverse's boulders, and only "
      "the odometry carries it ([the fix gate's design note](docs/design/fix-gate.md) has the trade-offs). On perfectly "
      f"calibrated odometry the oracle leaves at most {cm(max(cal) if cal else None)} cm: the data allow the target, "
      "but out of the prior's sight a 2 cm budget over an unseen path of rms L metres asks for the last fix's yaw "
      "within 0.02 / L rad (0.12° at L = 9.7 m) and the drift calibrated to a fraction of a percent of scale and "
      "a fifth of its yaw rate; the online calibration from a handful of fixes does not get there.")
held = []
for h in (2, 3):
    rep = json.load(open(f"{out}/stream_paper_seed{h}.json"))
    online = [p["rmse"]["online_m"] for p in rep["pairs"] if p["rmse"]["online_m"] is not None]
    held.append((h, rep["aggregate"], sum(1 for x in online if x <= 0.02), len(rep["pairs"])))
print()
print("Held out (the calibration priors `[calibration]` were chosen on the paper pairs at seed 1): "
      + "; ".join(f"seed {h}: online median {cm(a['median_rmse_online_m'])} cm, ≤ 2 cm on {n} of {m}, "
                  f"{a['wrong_fixes']} wrong fixes" for h, a, n, m in held)
      + ". Far from the prior the online error is the drift still uncalibrated when the query leaves the "
      "prior's boulders ([the note](docs/design/odometry-bias-prior.md)).")
print()
print("### With the odometry's calibration carried over from earlier drives")
print()
print("A rover's odometry errs alike from drive to drive. `--carry-calibration others` first replays every "
      "ordered pair sharing a boulder among the 13 traverses the paper pairs do not use (156 drives, random "
      "walks seeded with the seed + 1000), each starting from the median of the earlier drives' estimated "
      "biases; the paper pairs then start from the median of all of them, with its standard error as the "
      "calibration priors' σ (`[calibration.known]`, `prior_*`). Command: `segloc eval stream --pairs paper "
      "--json --seed S --carry-calibration others`. Seeds 1–5 chose the rule (median and standard error, "
      "not the last drive's estimate or the mean); seeds 6–8 were run once, after.")
print()
print("| seed | carried scale error (%) | carried yaw drift (rad/m) | ≤ 2 cm | online median / max (cm) | 3→7 | 5→7 | 5→12 | 7→12 | wrong fixes | without it: ≤ 2 cm, median |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
fresh = {1: paper}
for h in (2, 3):
    fresh[h] = json.load(open(f"{out}/stream_paper_seed{h}.json"))
carried_under = []
for h in range(1, 9):
    rep = json.load(open(f"{out}/stream_paper_carried_seed{h}.json"))
    k = rep["carried_calibration"]["known"]
    sg = rep["carried_calibration"]["sigma"]
    on = {(p["prior"], p["query"]): p["rmse"]["online_m"] for p in rep["pairs"]}
    n = sum(1 for x in on.values() if x is not None and x <= 0.02)
    carried_under.append(n)
    a = rep["aggregate"]
    f = fresh.get(h)
    without = "–"
    if f:
        fn = sum(1 for p in f["pairs"] if p["rmse"]["online_m"] is not None and p["rmse"]["online_m"] <= 0.02)
        without = f"{fn} of {len(f['pairs'])}, {cm(f['aggregate']['median_rmse_online_m'])}"
    print(f"| {h}{' (held out)' if h >= 6 else ''} | {100 * k['scale_error']:.3f} ± {100 * sg['scale_error']:.3f} | "
          f"{k['yaw_drift_rad_per_m']:.6f} ± {sg['yaw_drift_rad_per_m']:.6f} | {n} of {len(on)} | "
          f"{cm(a['median_rmse_online_m'])} / {cm(a['max_rmse_online_m'])} | "
          f"{cm(on.get((3, 7)))} | {cm(on.get((5, 7)))} | {cm(on.get((5, 12)))} | {cm(on.get((7, 12)))} | "
          f"{a['wrong_fixes']} | {without} |")
print()
print(f"Every paper pair within 2 cm on {sum(1 for n in carried_under if n == 10)} of 8 seeds; the truth drawn is "
      "1 % and 0.001745 rad/m. What stays over is 5→12 or 3→7: the query drives 16.7 / 9.7 m (rms) out of the prior's "
      "sight after its last fix, where the last fix's own yaw error (a tenth of a degree is 3 cm at 20 m) is left.")
PY
)
if [[ $print == 1 ]]; then echo "$section"; else echo "$section" | python3 scripts/bench_section.py stream; fi
