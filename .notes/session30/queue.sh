#!/bin/bash
# usage: queue.sh JOBFILE  (lines: ROOT TRUTH SEED TAG); runs 2 at a time
JOBS=$1
run() { read root truth seed tag <<< "$1"; cd $root && OPENBLAS_NUM_THREADS=1 /work/venv/bin/python experiments/diagnose_independent.py --seed $seed --n-null 8 --truths $truth --out /tmp/s30/res/${tag}_${truth}_s${seed} > /tmp/s30/res/${tag}_${truth}_s${seed}.log 2>&1; }
export -f run
mkdir -p /tmp/s30/res
cat $JOBS | xargs -P 2 -I{} bash -c 'run "{}"'
echo ALLDONE > /tmp/s30/res/done_$(basename $JOBS)
