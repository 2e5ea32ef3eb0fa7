#!/usr/bin/env bash
# Reproduce every figure of the paper's section 5 (Wu, Chang & Housner 1989) with the
# shipped models, as SVG + PNG under docs/figures/:
#   Mini-Mast bay deployment (5.1): Figs 7-8 longeron mid-span bending/twisting against Z,
#     9-10 diagonal bending against Z, 11-13 axial forces, 14 longeron upper-end moment
#     against longeron rotation, plus the driving force;
#   flapping blade (5.2): Figs 16-17 mid-span moment at 3 and 6 rad/s, 18 Campbell diagram
#     (FFT of 33 simulations, eigenvalue branches tracked by MAC, Southwell, harmonics),
#     19 moment history at 8 rad/s (resonance/beating).
# Usage: examples/reproduce_section5.sh            (results in target/section5/)
#        OUT=dir REUSE=1 examples/reproduce_section5.sh   (skip runs whose file exists)
# Cost on a shared 2-core machine: ~25 s Mini-Mast, ~7 min blade campaign, ~2 min the
# long 8 rad/s run.
set -euo pipefail
cd "$(dirname "$0")/.."
[[ "${NOBUILD:-0}" == 1 ]] || cargo build --release --quiet
L=target/release/latdyn
OUT=${OUT:-target/section5}
FIG=docs/figures
mkdir -p "$OUT" "$FIG"
have() { [[ "${REUSE:-0}" == 1 && -f "$1" ]]; }
plot() { # plot NAME ARGS... : SVG and PNG of one figure
  local name=$1; shift
  $L plot "$@" -o "$FIG/$name.svg" 2>/dev/null
  $L plot "$@" -o "$FIG/$name.png" --size 900x560
}

# --- Mini-Mast bay, full deployment (T = 1 s, held to 1.2 s) -------------------------
MM=$OUT/minimast.h5
have "$MM" || $L run models/minimast_bay.toml -o "$MM"
Z="--x upper_z.z"   # z of triangle B's reference point = Z + 0.02379 m
plot fig07_longeron_mid_bending "$MM" $Z --y longeron_mid.My \
  --title "Fig 7: longeron 1 mid-span bending My vs z of the upper triangle"
plot fig07b_longeron_mid_bending_Mz "$MM" $Z --y longeron_mid.Mz \
  --title "Fig 7: longeron 1 mid-span bending Mz vs z of the upper triangle"
plot fig08_longeron_mid_twist "$MM" $Z --y longeron_mid.T \
  --title "Fig 8: longeron 1 mid-span twisting moment vs z of the upper triangle"
plot fig09_diagonal_a_bending "$MM" $Z --y diagonal_a_mid.My \
  --title "Fig 9: diagonal half A mid-span bending vs z of the upper triangle"
plot fig10_diagonal_b_bending "$MM" $Z --y diagonal_b_mid.My \
  --title "Fig 10: diagonal half B mid-span bending vs z of the upper triangle"
plot fig11_13_axial_forces "$MM" --sensor longeron_axial --sensor diagonal_axial \
  --sensor diagonal_b_mid.N --title "Figs 11-13: axial forces (+ tension), longeron and diagonal halves A, B"
plot fig14_longeron_top_moment_vs_rotation "$MM" --x longeron_rotation.angle --y longeron_top.My \
  --title "Fig 14: longeron 1 upper-end bending vs longeron rotation (rad)"
plot minimast_drive_force "$MM" --sensor drive_force \
  --title "Force of the z driver on the upper triangle"

# --- Flapping blade: rotor-speed campaign, 33 speeds 1..9 rad/s ----------------------
BC=$OUT/blade_campaign.h5
have "$BC" || $L sweep models/flapping_blade.toml --vary omega=1:9:33 --set dt=0.005 --frequency mid_moment -o "$BC"  # dt of docs/studies/blade_speed_campaign.md
BM=$OUT/blade_modes.json
have "$BM" || $L modes models/flapping_blade.toml --vary omega=1:9:33 --count 3 --json > "$BM"
# variants 8 and 20 of the campaign are Omega = 3 and 6 rad/s
plot fig16_blade_moment_omega3 "$BC" --sensor mid_moment --variants 8 \
  --title "Fig 16: blade mid-span flap moment, Omega = 3 rad/s"
plot fig17_blade_moment_omega6 "$BC" --sensor mid_moment --variants 20 \
  --title "Fig 17: blade mid-span flap moment, Omega = 6 rad/s"
# Southwell: w0 = 3.9266^2 sqrt(EI/(rhoA L^4)) = 12.900 rad/s, K = 6.4 (models/flapping_blade.toml)
plot fig18_campbell "$BC" --campbell omega --derived first_bending_hz --modes "$BM" \
  --southwell 12.900,6.4 --harmonics 6 --title "Fig 18: flapping blade"
B8=$OUT/blade_omega8.h5
have "$B8" || $L run models/flapping_blade.toml --set omega=8 --set t_end=40 -o "$B8"
plot fig19_blade_resonance_omega8 "$B8" --sensor mid_moment \
  --title "Fig 19: blade mid-span flap moment, Omega = 8 rad/s (near the 3-per-rev crossing)"
echo "figures written to $FIG/"
