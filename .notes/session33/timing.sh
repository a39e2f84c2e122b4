#!/bin/bash
cd /tmp/s33/multi
for model in cascade cascade-preisach-gauss; do
 for code in old snap33g; do
  root=/tmp/s33/$code; [ $code = snap33g ] && root=/tmp/snap33g
  s=$(date +%s.%N)
  XDG_CACHE_HOME=/tmp/s33/cache_t4_$code OPENBLAS_NUM_THREADS=1 /work/venv/bin/python -u /work/main/.notes/session27/runcli.py $root fit r1.csv r2c.csv --model $model --split none --no-figures --out t4_${code}_$model > t4_${code}_$model.log 2>&1
  e=$(date +%s.%N)
  echo "$model $code rc=$? wall=$(echo "$e - $s" | bc)" >> /tmp/s33/timing.txt
 done
done
