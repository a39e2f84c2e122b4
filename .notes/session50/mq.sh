#!/bin/bash
core=$1; shift
for job in "$@"; do
  s=${job%:*}; v=${job#*:}
  OPENBLAS_NUM_THREADS=1 taskset -c $core /work/main/.venv/bin/python /tmp/s50/multi.py $s $v /tmp/s50/multi/rows.jsonl > /tmp/s50/multi/log_${s}_$v.txt 2>&1
done
