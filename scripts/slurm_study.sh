#!/bin/bash
# Runs a subslam study on a Slurm cluster: a job array of N slices, then a job that merges
# them when every slice has succeeded (docs/reproducing.md).
#
#   scripts/slurm_study.sh STUDY OUT N [subslam study flags, e.g. --trials 20]
#
# Prints the two job ids; the table is then in OUT/merged/summary.md (`subslam plot
# OUT/merged` draws its figures where matplotlib is installed). Extra sbatch options
# (partition, account, CPUs per task) go in SBATCH_OPTIONS, e.g.
#   SBATCH_OPTIONS="--partition=short --cpus-per-task=4" scripts/slurm_study.sh hybridslam /scratch/hs 50
set -euo pipefail
if (($# < 3)); then
  sed -n '2,10p' "$0" >&2
  exit 2
fi
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
STUDY="$1" OUT="$2" N="$3"
shift 3
SUBSLAM="${SUBSLAM:-$ROOT/build/apps/subslam}"
mkdir -p "$OUT"
array=$(STUDY="$STUDY" OUT="$OUT" SUBSLAM="$SUBSLAM" sbatch --parsable --export=ALL --array="1-$N" \
        --chdir="$OUT" ${SBATCH_OPTIONS:-} "$ROOT/scripts/study.sbatch" "$@")
slices=()
for ((k = 1; k <= N; ++k)); do slices+=("$OUT/slice_$k"); done
merge=$(sbatch --parsable --dependency="afterok:$array" --job-name=subslam-merge --chdir="$OUT" \
        --output="$OUT/subslam-merge-%j.out" ${SBATCH_OPTIONS:-} \
        --wrap="$SUBSLAM study merge ${slices[*]} --plots=false --out $OUT/merged")
echo "slices: job $array (array 1-$N); merge: job $merge -> $OUT/merged/summary.md"
