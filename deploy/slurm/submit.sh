#!/usr/bin/env bash
# Renders a pipeline on a Slurm cluster: a job array of TASKS render tasks (default 8, at most one
# per frame and at most the cluster's MaxArraySize), then one assemble job that runs only if
# every task succeeded (afterok) and is removed if one fails (--kill-on-invalid-dep=yes).
#
#   deploy/slurm/submit.sh PIPELINE OUT [TASKS]
#
# OUT must be on a file system every node sees. Environment:
#   STEREOTRACE           the stereotrace executable the nodes run (default: stereotrace on PATH)
#   STEREOTRACE_SBATCH    extra sbatch options for both jobs, e.g. "--partition=render --cpus-per-task=16"
#   STEREOTRACE_LOGS      the jobs' log folder (default: OUT/slurm-logs)
# Prints "render=ARRAY_JOB_ID assemble=JOB_ID".
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
pipeline=${1:?usage: submit.sh PIPELINE OUT [TASKS]}
out=${2:?usage: submit.sh PIPELINE OUT [TASKS]}
tasks=${3:-8}
bin=${STEREOTRACE:-stereotrace}
read -r -a extra <<< "${STEREOTRACE_SBATCH:-}"

# Refuse a bad pipeline here, before any job is queued (check exits 2 and says why).
report=$("$bin" check "$pipeline")
# `check` reports "... frames A..B)": no more tasks than frames.
if [[ $report =~ frames\ ([0-9]+)\.\.([0-9]+) ]]; then
    frames=$(( BASH_REMATCH[2] - BASH_REMATCH[1] + 1 ))
    (( tasks > frames )) && tasks=$frames
fi
# Array indices must stay below MaxArraySize (slurm.conf; 1001 when unset).
max=$(scontrol show config | awk -F'= *' '/^MaxArraySize/ {print $2}')
max=${max:-1001}
(( tasks > max )) && tasks=$max
(( tasks >= 1 )) || { echo "submit.sh: TASKS must be at least 1" >&2; exit 2; }

logs=${STEREOTRACE_LOGS:-$out/slurm-logs}
mkdir -p "$out" "$logs"
render=$(sbatch --parsable "${extra[@]}" --array="0-$((tasks - 1))" \
    --output="$logs/render-%A_%a.log" \
    --export=ALL,STEREOTRACE="$bin" "$here/render.sbatch" "$pipeline" "$out")
render=${render%%;*}
assemble=$(sbatch --parsable "${extra[@]}" --dependency="afterok:$render" --kill-on-invalid-dep=yes \
    --output="$logs/assemble-%j.log" \
    --export=ALL,STEREOTRACE="$bin" "$here/assemble.sbatch" "$pipeline" "$out")
assemble=${assemble%%;*}
echo "render=$render assemble=$assemble"
