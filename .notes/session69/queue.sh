#!/bin/bash
# usage: queue.sh LISTFILE  (lines "truth seed"); two workers pull from the list
LIST=$1
worker() {
  while true; do
    line=$(flock /tmp/s69/q.lock sh -c "head -n1 $LIST; sed -i 1d $LIST")
    [ -z "$line" ] && break
    set -- $line
    cd /tmp/h69 && OPENBLAS_NUM_THREADS=1 XLA_FLAGS="--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1" PYTHONPATH=/tmp/h69 timeout 2400 /work/main/.venv/bin/python experiments/diagnose_independent.py --seed $2 --n-null 8 --truths $1 --out /tmp/s69/out/$1_$2 > /tmp/s69/out/$1_$2.log 2>&1
  done
}
worker & worker & wait
