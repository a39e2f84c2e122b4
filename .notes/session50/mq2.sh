#!/bin/bash
core=$1; shift
for job in "$@"; do
  s=${job%:*}; v=${job#*:}
  PYTHONPATH=/tmp/s50/new OPENBLAS_NUM_THREADS=1 taskset -c $core /work/main/.venv/bin/python /tmp/s50/multi.py $s $v /tmp/s50/multi/rows_new.jsonl > /tmp/s50/multi/lognew_${s}_$v.txt 2>&1
done
