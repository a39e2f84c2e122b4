#!/bin/bash
# usage: run.sh ROOT TAG CMD...   -> one CLI command with peak RSS and wall time appended to summary.txt
root=$1; tag=$2; shift 2
s=$(date +%s)
XDG_CACHE_HOME=/tmp/s32/cache_smoke OPENBLAS_NUM_THREADS=1 /usr/bin/time -f "%M" -o /tmp/s32/smoke/$tag.mem /work/venv/bin/python -u /work/main/.notes/session27/runcli.py $root "$@" > /tmp/s32/smoke/$tag.log 2>&1
rc=$?
e=$(date +%s)
echo "$tag rc=$rc wall=$((e-s))s peakMB=$(( $(tail -1 /tmp/s32/smoke/$tag.mem) / 1000 )) :: $*" >> /tmp/s32/smoke/summary.txt
