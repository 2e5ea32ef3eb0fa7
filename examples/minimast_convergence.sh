#!/usr/bin/env bash
# Mesh and step convergence of the Mini-Mast bay deployment (models/README.md table):
# elements 2/4/8 at dt = 1e-3, dt 2e-3/1e-3/5e-4 with 4 elements. Prints a Markdown table
# of the peak longeron mid-span bending (resultant), the peak |driver force| and the turn
# of triangle B at T and at t_end. Needs python3 (stdlib only). ~3 min on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
[[ "${NOBUILD:-0}" == 1 ]] || cargo build --release --quiet
L=target/release/latdyn
OUT=${OUT:-target/section5/convergence}
mkdir -p "$OUT"
for case in "2 1e-3" "4 1e-3" "8 1e-3" "4 2e-3" "4 5e-4"; do
  set -- $case
  f="$OUT/e$1_dt$2.json"
  [[ "${REUSE:-0}" == 1 && -f "$f" ]] || $L run models/minimast_bay.toml --set elements=$1 --set dt=$2 --json > "$f"
done
python3 - "$OUT" <<'PY'
import json, math, sys, glob, os
print("| elements | dt [s] | steps (rejected) | peak longeron mid bending [N·m] | peak |drive force| [kN] | turn at T [°] | turn at t_end [°] | wall [s] |")
print("|---|---|---|---|---|---|---|---|")
for case in ["e2_dt1e-3", "e4_dt1e-3", "e8_dt1e-3", "e4_dt2e-3", "e4_dt5e-4"]:
    d = json.load(open(os.path.join(sys.argv[1], case + ".json")))
    s = d["sensors"]
    t = s["upper_z"]["t"]
    lm = s["longeron_mid"]["values"]
    peak = max(math.hypot(v[4], v[5]) for v in lm)
    drive = max(abs(v[0]) for v in s["drive_force"]["values"])
    iT = min(range(len(t)), key=lambda i: abs(t[i] - 1.0))
    up = s["upper_z"]["values"]
    e, dt = case[1:].split("_dt")
    print(f"| {e} | {dt} | {d['steps']} ({d['rejected_steps']}) | {peak:.2f} | {drive/1e3:.3f} | "
          f"{math.degrees(up[iT][5]):.3f} | {math.degrees(up[-1][5]):.3f} | {d['wall_s']:.1f} |")
PY
