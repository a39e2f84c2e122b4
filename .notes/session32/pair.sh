#!/bin/bash
# usage: pair.sh TAG ROOT REC  -> one cold CLI fit, prints wall seconds
tag=$1; root=$2; rec=$3
rm -rf /tmp/s32/pair/c_$tag /tmp/s32/pair/o_$tag
s=$(date +%s.%N)
XDG_CACHE_HOME=/tmp/s32/pair/c_$tag OPENBLAS_NUM_THREADS=1 /work/venv/bin/python -u /work/main/.notes/session27/runcli.py $root fit $rec --no-figures --out /tmp/s32/pair/o_$tag > /tmp/s32/pair/log_$tag.txt 2>&1
e=$(date +%s.%N)
echo "$tag $(echo "$e - $s" | bc)"
