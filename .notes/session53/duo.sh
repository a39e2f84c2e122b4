#!/bin/bash
# duo.sh A B : both at once, A on core 0 and B on core 1, then swapped
A=$1; B=$2; shift 2
for round in 1 2; do
  if [ $round = 1 ]; then ca=0; cb=1; else ca=1; cb=0; fi
  OPENBLAS_NUM_THREADS=1 taskset -c $ca /work/main/.venv/bin/python /work/main/.notes/session50/t1.py $A "$@" > /tmp/s53/duo_a_$round.txt 2>&1 &
  OPENBLAS_NUM_THREADS=1 taskset -c $cb /work/main/.venv/bin/python /work/main/.notes/session50/t1.py $B "$@" > /tmp/s53/duo_b_$round.txt 2>&1 &
  wait
  echo "round $round: A(core $ca) $(tail -1 /tmp/s53/duo_a_$round.txt) | B(core $cb) $(tail -1 /tmp/s53/duo_b_$round.txt)"
done
