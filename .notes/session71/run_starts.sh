#!/bin/bash
# two workers over a list of "seed kind name"
LIST=$1
worker() {
  while true; do
    line=$(flock /tmp/s71/probe/q.lock sh -c "head -n1 $LIST; sed -i 1d $LIST")
    [ -z "$line" ] && break
    set -- $line
    cd /tmp/h71 && OPENBLAS_NUM_THREADS=1 PYTHONPATH=/tmp/h71 timeout 1200 /work/main/.venv/bin/python /tmp/s71/probe/delay_starts.py $1 $2 $3 $4 > /tmp/s71/probe/st_$3_$1_$2_$4.log 2>&1
  done
}
worker & worker & wait
