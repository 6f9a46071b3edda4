#!/usr/bin/env bash
# CUDA checks and GPU throughput in one pass: the CUDA tests (env, turbulence, torch/warp parity
# and torch.compile on the GPU), then `falcon-rl bench` on the GPU from 1 to 1,048,576 envs,
# then the MPPI planning time per control step on the GPU.
# Usage: bash benchmarks/cuda_check.sh [OUTDIR]     (python from $PYTHON, default python3)
set -u
. "$(dirname "$0")/gpu_setup.sh" "${1:-runs/cuda}"
$py -m pytest -q -p no:cacheprovider -rs tests/test_cuda.py tests/test_warp_parity.py -k cuda \
    2>&1 | tail -15 | tee "$out/tests.txt"
$py -m falcon_rl.cli bench --device cuda --backend warp,torch --envs 1,1024,16384,262144,1048576 \
    --steps 50 --trials 5 --out "$out/bench" 2>&1 | grep -v "^bench" | tee "$out/bench.txt"
timeout 120 $py -m falcon_rl.cli bench --device cuda --backend torch-compile --envs 16384,1048576 \
    --steps 50 --trials 5 --no-env --out "$out/bench_compile" 2>&1 | grep -v "^bench" | tee "$out/bench_compile.txt"
timeout 90 $py -m falcon_rl.cli eval --controller mppi --task altitude --airframe volantex_ranger \
    --episodes 4 --seconds 10 --backend warp --device cuda --out "$out/mppi" 2>&1 | tail -15 | tee "$out/mppi.txt"
