#!/bin/bash
# usage: OPTS='{"memory": "rule"}' queue_opts.sh ROOT OUTDIR CORE SEED...   (queue.sh with fit_record options)
root=$1; outdir=$2; core=$3; shift 3
mkdir -p "$outdir"
for s in "$@"; do
  line=$(/work/main/.venv/bin/python /work/main/.notes/session48/random_cells.py "$s")
  minutes=$(echo "$line" | cut -f2); cell=$(echo "$line" | cut -f3)
  SMAFL_FIT_OPTS="$OPTS" SMAFL_CELLS_JSON="$cell" OPENBLAS_NUM_THREADS=1 taskset -c "$core" /work/main/.venv/bin/python \
    /work/main/experiments/base_fit_before_after.py "$root" "$outdir/s$s.json" "$minutes" "$s" > "$outdir/s$s.log" 2>&1
done
