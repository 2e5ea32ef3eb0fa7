#!/usr/bin/env bash
# The design studies of issue 6, each one `latdyn sweep`, tables written to docs/studies/:
#  - Mini-Mast bay: longeron hinge axes turned by -0.1..0.1 rad (51 designs) ->
#    docs/studies/minimast_hinge_sweep.md (peak longeron/diagonal bending, peak drive
#    force, outcome per design, best design).
#  - flapping blade: 33 rotor speeds 1..9 rad/s with the FFT bending frequency, plus the
#    MAC-tracked eigenvalue branches -> docs/studies/blade_speed_campaign.md (frequency vs
#    Southwell per speed, resonance speeds with 3, 4, 5 Omega). Both studies together: ~4 min
#    on a 2-core machine (measured in session 4).
# Needs python3 with h5py and numpy (as the tests do). OUT=dir REUSE=1 reuses existing files
# (the blade files are shared with examples/reproduce_section5.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
[[ "${NOBUILD:-0}" == 1 ]] || cargo build --release --quiet
L=target/release/latdyn
OUT=${OUT:-target/section5}
mkdir -p "$OUT" docs/studies
have() { [[ "${REUSE:-0}" == 1 && -f "$1" ]]; }
MS=$OUT/minimast_hinge_sweep.h5
have "$MS" || $L sweep models/minimast_bay.toml --vary longeron_axis_angle=-0.1:0.1:51 -o "$MS"
python3 examples/design_studies.py minimast "$MS" docs/studies/minimast_hinge_sweep.md
# the same designs screened quasi-statically (sweep --path), timed beside the dynamic sweep
python3 examples/minimast_quasistatic.py "$L" --study
BC=$OUT/blade_campaign.h5
have "$BC" || $L sweep models/flapping_blade.toml --vary omega=1:9:33 --set dt=0.005 --frequency mid_moment -o "$BC"  # dt of docs/studies/blade_speed_campaign.md
BM=$OUT/blade_modes.json
have "$BM" || $L modes models/flapping_blade.toml --vary omega=1:9:33 --count 3 --json > "$BM"
python3 examples/design_studies.py blade "$BC" "$BM" docs/studies/blade_speed_campaign.md
