#!/usr/bin/env bash
# One device check on a lent GPU machine: the machine, a correctness subset of the test suite on the
# GPU backend, then benchmarks/bench_gpu.py (GPU vs CPU side by side).  Always exits 0; the statuses
# are printed at the end and written to $OUT/status.txt.
#
#   bash benchmarks/gpu_check.sh                     # on the device machine, from the repo root ($OUT set by the tool)
#   OUT=/tmp/x SMAFL_GPU_QUICK=1 bash benchmarks/gpu_check.sh   # CPU smoke run here (tiny sizes)
#
# Environment: OUT (results folder, default ./gpu_check_out), SMAFL_GPU_QUICK=1 (tiny sizes, a 1-file test
# subset), SMAFL_GPU_FAKE=1 (a second host CPU device stands in for the GPU: tests the placement),
# SMAFL_GPU_TOTAL_S (wall-time target for tests + benchmark, default 420: the benchmark gets what the
# tests left, at most 270 s), PYTHON (default python3).
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-$PWD/gpu_check_out}
PY=${PYTHON:-python3}
QUICK=${SMAFL_GPU_QUICK:-0}
TOTAL_S=${SMAFL_GPU_TOTAL_S:-420}
mkdir -p "$OUT"
export XLA_PYTHON_CLIENT_PREALLOCATE=false PYTHONUNBUFFERED=1
start=$(date +%s)

echo "== machine"
if command -v nvidia-smi >/dev/null 2>&1; then
    nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv
else
    echo "nvidia-smi: not found (no NVIDIA driver here)"
fi
nproc
"$PY" - <<'EOF'
import sys
from importlib.metadata import PackageNotFoundError, version

import jax

names = ("jax", "jaxlib", "jax-cuda13-plugin", "numpy", "equinox", "optimistix", "lineax", "jaxopt", "emcee", "pytest-xdist")
found = []
for name in names:
    try:
        found.append(f"{name} {version(name)}")
    except PackageNotFoundError:
        found.append(f"{name} MISSING")
print("python", sys.version.split()[0], "|", " | ".join(found))
print("default backend", jax.default_backend(), "| devices", jax.devices())
EOF

if [ "$QUICK" = "1" ]; then
    TESTS=(tests/test_operators_weighted.py)
    WORKERS=2
    BENCH_ARGS="--quick --tiers 1"
else
    # numpy-loop references for the play bank (all exact forms), the weighted sum, the models and their
    # gradients vs finite differences; five slow cases left out: 99 s on one core of the dev machine
    TESTS=(tests/test_operators.py tests/test_operators_weighted.py tests/test_models.py tests/test_ops.py)
    for t in "test_ops.py::test_relays_crisp_and_ramp_all_forms[0]" "test_ops.py::test_play_gradients_match_finite_differences[chunked]" \
        "test_ops.py::test_relay_gradients_match_finite_differences[segmented]" \
        "test_ops.py::test_affine_gradients_match_finite_differences[chunked]" \
        "test_models.py::test_eupi_polynomial_continues_linearly_outside_its_range"; do
        TESTS+=(--deselect "tests/$t")
    done
    WORKERS=4
    BENCH_ARGS=""
fi
[ "${SMAFL_GPU_FAKE:-0}" = "1" ] && BENCH_ARGS="$BENCH_ARGS --fake-accel"

echo "== tests on the default backend: ${TESTS[*]}"
t0=$(date +%s)
set -o pipefail
timeout 200 "$PY" -m pytest -q --maxfail=10 -p no:cacheprovider -n "$WORKERS" "${TESTS[@]}" 2>&1 | tee "$OUT/tests.log"
test_rc=$?
set +o pipefail
test_s=$(($(date +%s) - t0))
echo "tests: exit $test_rc in ${test_s} s"

used=$(($(date +%s) - start))
budget=$((TOTAL_S - used - 30))
[ "$budget" -gt 270 ] && budget=270
[ "$budget" -lt 90 ] && budget=90
echo "== benchmark (budget ${budget} s; tests and setup used ${used} s)"
t0=$(date +%s)
timeout $((budget + 60)) "$PY" benchmarks/bench_gpu.py $BENCH_ARGS --budget-s "$budget" --out "$OUT" 2>&1 | tee "$OUT/bench.log"
bench_rc=${PIPESTATUS[0]}
bench_s=$(($(date +%s) - t0))
if [ "$bench_rc" -ne 0 ]; then
    echo "benchmark exited $bench_rc; table of what results.json holds:"
    "$PY" benchmarks/bench_gpu.py --render --out "$OUT" || true
fi

status="tests: exit $test_rc (${test_s} s; 0 = all passed, 124 = timed out) | bench: exit $bench_rc (${bench_s} s) | total $(($(date +%s) - start)) s"
echo "$status" | tee "$OUT/status.txt"
exit 0
