#!/bin/bash
# Throughput against the number of array tasks: submits the campaign (submit.sh) once
# per task count and prints, per run, the wall time from submission to the end of the
# merge job and the variants per second. README "Campaigns on a cluster" quotes it.
#
#   LATDYN=$PWD/target/release/latdyn \
#   CAMPAIGN="$PWD/models/rotating_cantilever.toml --vary omega=1:5:96 --set t_end=4" \
#   OUT=/tmp/scaling examples/slurm/scaling.sh 1 2 4
set -euo pipefail
: "${LATDYN:?}" "${CAMPAIGN:?}" "${OUT:?}"
here=$(dirname "$(readlink -f "$0")")
for n in "$@"; do
  out="$OUT/tasks_$n"
  rm -rf "$out"
  t0=$(date +%s.%N)
  read -r array merge < <(SHARDS=$n OUT=$out "$here/submit.sh")
  while [ -n "$(squeue -h -j "$array,$merge" -o %i 2>/dev/null)" ]; do sleep 0.2; done
  t1=$(date +%s.%N)
  python3 - "$out/merge.json" "$n" "$t0" "$t1" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
n, wall = int(sys.argv[2]), float(sys.argv[4]) - float(sys.argv[3])
print(json.dumps({"tasks": n, "variants": r["variants"], "completed": r["completed"],
                  "wall_s": round(wall, 2), "variants_per_s": round(r["variants"] / wall, 2),
                  "merge_s": round(r["wall_s"], 3)}))
PY
done
