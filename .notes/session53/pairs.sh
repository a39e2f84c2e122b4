#!/bin/bash
# usage: pairs.sh N ROOT_A ROOT_B  -> alternating fresh-process timings
N=$1; A=$2; B=$3
for i in $(seq 1 $N); do
  for R in $A $B; do
    /usr/bin/time -f "  wall %e user %U sys %S" /work/main/.venv/bin/python /work/main/.notes/session50/t1.py $R 2>&1 | tail -2 | tr '\n' ' '; echo
  done
done
