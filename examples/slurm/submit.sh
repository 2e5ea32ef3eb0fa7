#!/bin/bash
# Submit a latdyn campaign to Slurm: a job array of SHARDS shard tasks, then a merge job
# that waits for the whole array (--dependency=afterany: it runs also when tasks failed
# or were killed, and reports what is missing). Prints "ARRAY_ID MERGE_ID".
#
#   LATDYN=$PWD/target/release/latdyn \
#   CAMPAIGN="$PWD/models/rotating_cantilever.toml --vary omega=0:10:2000" \
#   SHARDS=64 OUT=$PWD/campaign examples/slurm/submit.sh [extra sbatch options]
#
# Extra options (partition, account, --time=...) go to both jobs. Afterwards:
# $OUT/campaign.h5 and $OUT/merge.json; if incomplete, `sbatch resume.sbatch`
# (same environment) completes it.
set -euo pipefail
: "${LATDYN:?}" "${CAMPAIGN:?}" "${SHARDS:?}" "${OUT:?}"
here=$(dirname "$(readlink -f "$0")")
mkdir -p "$OUT"
export LATDYN CAMPAIGN SHARDS OUT
array=$(sbatch --parsable --array=1-"$SHARDS" --output="$OUT/shard_%a.log" "$@" \
  "$here/array.sbatch")
array=${array%%;*}
merge=$(sbatch --parsable --dependency=afterany:"$array" --output="$OUT/merge.log" "$@" \
  "$here/merge.sbatch")
merge=${merge%%;*}
echo "$array $merge"
