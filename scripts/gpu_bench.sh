#!/usr/bin/env bash
# Issue 18's device figures in one run, on a machine with an NVIDIA GPU and `pip install -e ".[cuda]"`
# (docs/performance.md, "GPU"). Writes everything under $OUT (default gpu-bench/):
#   device.txt          nvidia-smi and numba-cuda's view of the device
#   cases_methods.json  10 steps x 3 methods, GPU float64 against the CPU backend (tests/cuda_sim_cases.py,
#                       here on the real device: the acceptance bound is 1e-9 relative)
#   cases_float32.json  the float32 tank and free fall against the CPU's float64
#   gpu64.md/.json      ipsph bench --backend cuda --scaling 100000 1000000 4000000 (float64; CPU beside at 100k)
#   gpu32.md/.json      the same in float32
# Usage: scripts/gpu_bench.sh [SIZES...]   (default sizes: 100000 1000000 4000000)
set -euo pipefail
OUT=${OUT:-gpu-bench}
SIZES=${*:-100000 1000000 4000000}
mkdir -p "$OUT"
unset NUMBA_ENABLE_CUDASIM
{ nvidia-smi || true; python -c "from numba import cuda; cuda.detect()"; } > "$OUT/device.txt" 2>&1
IPSPH_CASES_ON_DEVICE=1 python tests/cuda_sim_cases.py methods > "$OUT/cases_methods.json"
IPSPH_CASES_ON_DEVICE=1 python tests/cuda_sim_cases.py float32 > "$OUT/cases_float32.json"
ipsph bench --backend cuda --precision float64 --scaling $SIZES --cpu-max-particles 100000 --no-peer \
    --markdown --json "$OUT/gpu64.json" > "$OUT/gpu64.md"
ipsph bench --backend cuda --precision float32 --scaling $SIZES --cpu-max-particles 0 --no-peer \
    --markdown --json "$OUT/gpu32.json" > "$OUT/gpu32.md"
cat "$OUT/gpu64.md" "$OUT/gpu32.md"
