#!/usr/bin/env bash
# A look-up table on a Slurm cluster: one array task per shard, then one gather job.
#
#   sbatch --array=0-99 examples/cluster/slurm_array.sh assets/sequences/lai_cab_sun.ron /scratch/$USER/lut
#   # when the array has finished (or: sbatch --dependency=afterok:<array job id> ...):
#   lumenscape gather /scratch/$USER/lut          # -> /scratch/$USER/lut/lut.csv
#
# Each task runs the shard SLURM_ARRAY_TASK_ID − SLURM_ARRAY_TASK_MIN of SLURM_ARRAY_TASK_COUNT
# (`lumenscape sequence` reads them itself). The output folder must be on a file system every
# node sees. A task that fails or is pre-empted can be resubmitted as is: finished points are
# skipped, a half-written point is run again (docs/guide/sequences.md).
#SBATCH --job-name=lumenscape-lut
#SBATCH --cpus-per-task=4
#SBATCH --mem=8G
#SBATCH --time=02:00:00
#SBATCH --output=lut-%A_%a.log
set -euo pipefail
SEQ=${1:?usage: sbatch --array=0-N slurm_array.sh SEQUENCE.ron OUT_DIR}
OUT=${2:?usage: sbatch --array=0-N slurm_array.sh SEQUENCE.ron OUT_DIR}
# Threads of the flux tracker: the CPUs Slurm gave this task.
export RAYON_NUM_THREADS=${SLURM_CPUS_PER_TASK:-1}
exec lumenscape sequence "$SEQ" --out "$OUT" --quiet --max-memory "${SLURM_MEM_PER_NODE:-8192}M"
