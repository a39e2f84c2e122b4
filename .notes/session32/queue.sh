#!/bin/bash
R=/tmp/snap2
cd /tmp/s32/smoke
for t in a b c d e; do
  ./run.sh $R fit_$t fit $t.csv --out o_$t
  ./run.sh $R sim_$t simulate o_$t/fit.json $t.csv --measured $t.csv --out sim_$t
done
./run.sh $R diag_a diagnose a.csv --out d_a
./run.sh $R diag_e diagnose e.csv --out d_e
./run.sh $R check_c check c.csv
