#!/usr/bin/env bash
# The whole pipeline on a synthetic shot, from a fresh machine:
#   install -> simulate a draw -> render its overhead video -> track it -> fit -> discover.
# Usage: scripts/demo.sh [OUTDIR]   (default: out/demo)
set -euo pipefail
source "$(dirname "$0")/_venv.sh"
cd "$ROOT"
OUT="${1:-out/demo}"
RIG="fixtures/rig.toml"
mkdir -p "$OUT"
say() { printf '\n\033[1m== %s\033[0m\n' "$*"; }

say "1/6 simulate a pebbled-ice draw (paper model) with a friction patch hidden at y = 3.5-5.5 m"
curltrack simulate --v0 1.4 --omega0 1.6 --rig "$RIG" \
    --effect friction_patch --param y_start_m=3.5 --param y_end_m=5.5 --param factor=1.6 \
    -o "$OUT/sim.csv"

say "2/6 render the overhead video (ladder camera, lens distortion, blur, noise, compression)"
curltrack render "$OUT/sim.csv" --rig "$RIG" -o "$OUT/shot.mp4" --truth "$OUT/truth.csv" \
    --seed 7 --camera ladder

say "3/6 track: video -> x(t), y(t), theta(t) and stop frames"
curltrack track "$OUT/shot.mp4" --rig "$RIG" -o "$OUT/shot.csv" --overlay "$OUT/overlay.mp4"

say "4/6 fit the paper's formulas"
curltrack fit "$OUT/shot.csv" --rig "$RIG" -o "$OUT/fit.json" --plot "$OUT/fit.png"

say "5/6 discover what the baseline model gets wrong"
curltrack discover "$OUT/shot.csv" -o "$OUT/report.json" --plot "$OUT/report.png"

say "6/6 a review page to check the track by eye (open it in a browser; no server needed)"
curltrack review "$OUT/shot.csv" --rig "$RIG" --report "$OUT/report.json" -o "$OUT/review.html"

python - "$OUT" <<'PY'
import json, sys
import numpy as np, pandas as pd
out = sys.argv[1]
shot, truth = pd.read_csv(f"{out}/shot.csv"), pd.read_csv(f"{out}/truth.csv")
m = shot.merge(truth, on="frame", suffixes=("", "_true"))
m = m[m.ok == 1]
err = np.hypot(m.x - m.x_true, m.y - m.y_true)
dth = np.degrees(m.theta - m.theta_true)
rep = json.load(open(f"{out}/report.json"))
print(f"\ntracking vs truth: position RMS {1e3*np.sqrt(np.mean(err**2)):.2f} mm, "
      f"theta RMS {np.sqrt(np.mean(dth**2)):.3f} deg over {len(m)} frames")
print(f"discovery verdict: {rep['verdict']}")
PY

say "outputs in $OUT"
ls -1 "$OUT" | sed "s|^|  $OUT/|"
