#!/usr/bin/env bash
# Relocalization accuracy on the real LunarLoc traverses, and landmark quality against the
# LAC ground-truth rock cells. Writes the section of BENCHMARKS.md between
# <!-- relocalization:begin --> and <!-- relocalization:end --> (nothing else is touched).
#
#   scripts/bench_relocalization.sh        (from anywhere)
# Environment: SEGLOC_DATA (default ../shared/data, relative to the repo root).
set -euo pipefail
repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$repo_root"
source scripts/bench_lib.sh
need_data lunarloc bench_relocalization
segloc_bin --example submap_negatives
out="$target/bench"
mkdir -p "$out"

echo "[bench_relocalization] landmarks" >&2
$bin eval landmarks --data "$data" --json > "$out/landmarks.json"
echo "[bench_relocalization] paper pairs 4-DOF" >&2
$bin eval lunarloc --data "$data" --pairs paper --trials 20 --seed 1 --dof 4 --json > "$out/paper4.json"
echo "[bench_relocalization] paper pairs 6-DOF" >&2
$bin eval lunarloc --data "$data" --pairs paper --trials 20 --seed 1 --dof 6 --json > "$out/paper6.json"
echo "[bench_relocalization] all 136 pairs 4-DOF" >&2
$bin eval lunarloc --data "$data" --pairs all --trials 10 --seed 1 --dof 4 --json > "$out/all4.json"
echo "[bench_relocalization] negatives: mirrored traverses and submaps" >&2
$bin eval lunarloc --data "$data" --pairs all --negatives --trials 20 --seed 1 --dof 4 --json > "$out/negatives.json"
SEGLOC_DATA="$data" "$target/release/examples/submap_negatives" 600 > "$out/submaps_negative.txt"
SEGLOC_DATA="$data" "$target/release/examples/submap_negatives" 600 positives > "$out/submaps_positive.txt"

python3 - "$out" "$(date -u '+%Y-%m-%d %H:%M UTC')" "$(lscpu | sed -n 's/^Model name: *//p' | head -1), $(nproc) cores" "$(git rev-parse --short HEAD)" <<'PY'
import json, sys
out, date, machine, commit = sys.argv[1:5]
L = json.load(open(f"{out}/landmarks.json"))
p4 = json.load(open(f"{out}/paper4.json")); p6 = json.load(open(f"{out}/paper6.json")); a4 = json.load(open(f"{out}/all4.json"))
def cm(x): return f"{100*x:.2f}"
lines = []
w = lines.append
w("## Relocalization on the real LunarLoc traverses")
w("")
w("Command: `scripts/bench_relocalization.sh` (writes this section only). "
  f"Date: {date}. Machine: {machine}. Commit `{commit}`. Times are wall clock, one process, default thread count.")
w("")
w("Each trial moves the query traverse (rover positions and every detection) by a random rigid transform "
  "(any yaw, ±20 m in x and y, ±1 m in z; 6-DOF also roll and pitch within ±10°), fuses it into landmarks in its "
  "moved frame and relocalizes it against the prior traverse's map. Translation error is ‖t‖ of "
  "`estimate · truth⁻¹` (the displacement of the world origin, the lander, within ~15 m of every boulder); "
  "a false accept is an accepted answer off by more than 10 cm or 1°. True common landmarks: mutual nearest "
  "neighbours within 10 cm of the two traverses' maps in the world frame.")
w("")
def table(rep, title, cmd, rows=True):
    w(f"### {title}")
    w("")
    w(f"`{cmd}`" + ("" if rows else " (per pair: the command's output)"))
    w("")
    if not rows:
        totals(rep)
        return
    w("| prior | query | landmarks (prior / query) | true common | success | false accepts | inliers (mean) | translation error mean / max (cm) | rotation error max (°) | time mean (ms) |")
    w("|---|---|---|---|---|---|---|---|---|---|")
    for p in rep["pairs"]:
        ok = [t for t in p["trials"] if t["correct"]]
        te = [t["translation_error_m"] for t in ok]; re_ = [t["rotation_error_deg"] for t in ok]
        inl = sum(t["inliers"] for t in p["trials"]) / len(p["trials"])
        tm = sum(t["time_ms"] for t in p["trials"]) / len(p["trials"])
        w(f"| {p['prior']} | {p['query']} | {p['prior_landmarks']} / {p['query_landmarks']} | {p['true_common']} | "
          f"{p['successes']}/{len(p['trials'])} | {p['false_accepts']} | {inl:.1f} | "
          f"{cm(sum(te)/len(te)) if te else '–'} / {cm(max(te)) if te else '–'} | {max(re_) if re_ else float('nan'):.3f} | {tm:.1f} |")
    w("")
    totals(rep)
def totals(rep):
    t = rep["totals"]
    w(f"Totals: success {t['successes']}/{t['trials']}, false accepts **{t['false_accepts']}**; translation error "
      f"mean {cm(t['translation_error_m']['mean'])} cm, median {cm(t['translation_error_m']['median'])} cm, "
      f"max {cm(t['translation_error_m']['max'])} cm; rotation error mean {t['rotation_error_deg']['mean']:.3f}°, "
      f"max {t['rotation_error_deg']['max']:.3f}°; time median {t['time_ms']['median']:.1f} ms, max {t['time_ms']['max']:.0f} ms.")
    w("")
table(p4, "Paper pairs, 4-DOF, 20 random transforms each", "segloc eval lunarloc --pairs paper --trials 20 --seed 1 --dof 4")
table(p6, "Paper pairs, 6-DOF, 20 random transforms each", "segloc eval lunarloc --pairs paper --trials 20 --seed 1 --dof 6", rows=False)
t = a4["totals"]
w("### All 136 pairs, 4-DOF, 10 random transforms each")
w("")
w("`segloc eval lunarloc --pairs all --trials 10 --seed 1 --dof 4`")
w("")
w(f"- trials {t['trials']}, successes {t['successes']}, **false accepts {t['false_accepts']}**")
w(f"- pairs sharing ≥ 8 true common landmarks: {sum(1 for p in a4['pairs'] if p['true_common'] >= 8)} of {len(a4['pairs'])}; their trials: {t['successes_with_8_common']}/{t['trials_with_8_common']} succeeded")
w(f"- fewest true common landmarks of any pair: {min(p['true_common'] for p in a4['pairs'])} (every traverse passes near the lander, so every pair overlaps)")
w(f"- translation error mean {cm(t['translation_error_m']['mean'])} cm, median {cm(t['translation_error_m']['median'])} cm, max {cm(t['translation_error_m']['max'])} cm; rotation error max {t['rotation_error_deg']['max']:.3f}°")
w(f"- time per relocalization: median {t['time_ms']['median']:.1f} ms, mean {t['time_ms']['mean']:.1f} ms, max {t['time_ms']['max']:.0f} ms (largest maps: traverse 13, ~500 landmarks)")
w("")
n = json.load(open(f"{out}/negatives.json"))["totals"]
sub_neg = open(f"{out}/submaps_negative.txt").read().strip().splitlines()
sub_pos = open(f"{out}/submaps_positive.txt").read().strip().splitlines()
w("### Negatives: maps no rigid motion aligns")
w("")
w("A traverse mirrored in x keeps a real map's density, spacing and extent, but no rigid motion maps it onto any "
  "traverse, its own original included: every accepted answer is a false accept (4-DOF only: in 6-DOF a mirrored, "
  "nearly planar boulder field is the original turned upside down).")
w("")
w("`segloc eval lunarloc --pairs all --negatives --trials 20 --seed 1 --dof 4` (the 136 pairs and every traverse "
  f"against its own mirror image): **{n['false_accepts']} accepted of {n['trials']}**; time per attempt median "
  f"{n['time_ms']['median']:.1f} ms.")
w("")
w("`cargo run --release --example submap_negatives -- 600 [positives]`: every traverse cut into 30 s windows "
  "(600 frames), each window's submap relocalized against the full map of every traverse, as a SLAM loop closure does. "
  "Mirrored windows:")
w("")
for line in sub_neg[-2:]:
    w(f"    {line}")
w("")
wrong = [l for l in sub_pos if l.startswith("traverse ")]
w("True windows against the other traverses' maps (an answer off by more than 10 cm or 1° at the lander is wrong; "
  "the last line compares every accepted answer's rotation error with the yaw σ its information matrix reports):")
w("")
for line in [l for l in sub_pos if not l.startswith("traverse ")]:
    w(f"    {line}")
w("")
w(f"The {len(wrong)} wrong answers (listed by the example) are the right associations with an imprecise yaw "
  "(6–7 inliers in submaps of 8–16 landmarks spread over 0.3–0.6 m), and their information matrices say so; "
  "a caller that gates by information, as the mission's fix gate does, is not misled.")
w("")
w("### Landmark quality against the LAC ground-truth rock cells")
w("")
w("`segloc eval landmarks` — fraction of points on a ground-truth rock cell, and on or beside one (8-neighbourhood), "
  "for the raw detections and for the fused landmarks (default fusion: cluster radius 0.2 m, ≥ 2 detections, range 1.5–8 m, median centroid).")
w("")
tot = [0,0,0,0,0,0]
per = []
for r in L["traverses"]:
    d, l = r["detections"], r["landmarks"]
    per.append((100*l['on_rock'], r['traverse']))
    tot[0]+=d['points']; tot[1]+=d['points']*d['on_rock']; tot[2]+=d['points']*d['near_rock']
    tot[3]+=l['points']; tot[4]+=l['points']*l['on_rock']; tot[5]+=l['points']*l['near_rock']
w(f"Detections (17 traverses, {tot[0]} points): {100*tot[1]/tot[0]:.1f}% on rock, {100*tot[2]/tot[0]:.1f}% on or beside; "
  f"landmarks ({tot[3]}): {100*tot[4]/tot[3]:.1f}% and {100*tot[5]/tot[3]:.1f}%.")
w(f"Per traverse, landmarks on rock from {min(per)[0]:.1f}% (traverse {min(per)[1]}) to {max(per)[0]:.1f}% "
  f"(traverse {max(per)[1]}); the per-traverse table: `segloc eval landmarks`. Raw detections are dominated by the "
  "large, well-seen boulders, so per detection they sit on rock more often than per landmark. Why "
  "`min_observations` stays 2: [docs/experiments.md](docs/experiments.md).")
text = "\n".join(lines)
sys.path.insert(0, "scripts")
from bench_section import write_section
write_section("BENCHMARKS.md", "relocalization", text)
print("wrote the relocalization section of BENCHMARKS.md", file=sys.stderr)
PY
