#!/bin/bash
# q.sh CORE TAG OPTS SEEDS...
core=$1; tag=$2; opts=$3; shift 3
for s in "$@"; do
  OPENBLAS_NUM_THREADS=1 taskset -c $core /work/main/.venv/bin/python /work/main/.notes/session48/probe_record.py /work/main $s /tmp/s49/p${s}${tag}.npz "$opts" 2>/dev/null | sed "s/^/$s $tag /" >> /tmp/s49/q_$tag.log
done
