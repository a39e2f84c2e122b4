#!/bin/bash
root=$1; outdir=$2; shift 2
mkdir -p "$outdir"
for s in "$@"; do
  line=$(/work/main/.venv/bin/python /work/main/.notes/session48/random_cells.py "$s")
  minutes=$(echo "$line" | cut -f2); cell=$(echo "$line" | cut -f3)
  SMAFL_CELLS_JSON="$cell" /work/main/.venv/bin/python \
    /work/main/experiments/base_fit_before_after.py "$root" "$outdir/s$s.json" "$minutes" "$s" > "$outdir/s$s.log" 2>&1
done
