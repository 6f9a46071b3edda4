#!/usr/bin/env bash
# Issue 17's GPU targets in one pass, on one CUDA GPU, in about nine minutes once the kernels are cached:
#   1. the CUDA tests (env rollouts, one-launch step = staged step, its CUDA graph = its launch, fused
#      tasks and their start of episodes, turbulence and trajectory parity on the GPU; the torch.compile
#      test is left to cuda_check.sh);
#   2. benchmarks/env_step.py on the GPU at 16,384 and 1,048,576 envs: the physics alone, the one-launch
#      step without TorchRL, the lean TorchRL env, a one-row partial reset and the trivial-EnvBase floor,
#      timed in the same rounds;
#   3. PPO altitude on the Volantex Ranger on the GPU, from scratch, with each recipe of $PPO_RECIPES
#      (NAME=FIELD=VALUE,FIELD=VALUE ... ; default: two candidates, below), stopping at the first
#      validation with RMSE <= 0.3 m: the whole command timed, its log and summary (with the loop's
#      collect / validate / learn split) kept.
# The first CUDA launch compiles the Warp kernels for the GPU (minutes: the physics module and the
# task's env step, each with the RK4 sub-steps inlined) and caches them; step 0 does it and reports
# the time, so that the later steps time warm kernels.
# Usage: bash benchmarks/gpu_targets.sh [OUTDIR]      (python from $PYTHON, default python3)
# Each step has its own time limit, so one that hangs or fails leaves the others their time; with
# $SNAPSHOT set, OUTDIR is packed into that .tgz after each step (checkpoints left out).
set -u
. "$(dirname "$0")/gpu_setup.sh" "${1:-runs/gpu_targets}"

snapshot() { [ -z "${SNAPSHOT:-}" ] || tar czf "$SNAPSHOT" -C "$out" --exclude=checkpoint.pt .; }

# The first CUDA env compiles the Warp kernels it launches (the physics module and the altitude env
# step) for this GPU unless they are cached: minutes (benchmarks/precompile_cuda.py makes them ahead).
start=$(date +%s)
timeout "${COMPILE_S:-600}" $py -c "from falcon_rl import make_env; make_env('altitude', 'volantex_ranger', num_envs=8,
backend='warp', device='cuda', seed=0).rollout(5)" 2>&1 | tail -3
echo "warp module compiled and cached: $(( $(date +%s) - start )) s" | tee -a "$out/gpu.txt"

start=$(date +%s)
timeout "${TESTS_S:-150}" $py -m pytest -q -p no:cacheprovider -rs tests/test_cuda.py tests/test_env_step_kernel.py \
    tests/test_fused_task.py tests/test_fused_start.py tests/test_turbulence.py tests/test_warp_parity.py \
    -k "cuda and not compiled" \
    2>&1 | tail -8 | tee "$out/tests.txt"
echo "tests: $(( $(date +%s) - start )) s" | tee -a "$out/tests.txt"
snapshot

start=$(date +%s)
timeout "${BENCH_S:-110}" $py benchmarks/env_step.py --device cuda --envs 16384,1048576 --trials 5 --block-s 0.5 \
    --cases "physics,fused step,fused step (CUDA graph),env lean,partial reset,torchrl floor (new outputs)" \
    --no-progress --out "$out/env_step" \
    2>&1 | tee "$out/env_step.txt"
echo "env_step: $(( $(date +%s) - start )) s" | tee -a "$out/env_step.txt"
snapshot

# name=overrides, space-separated; every recipe runs with the same seed, stop condition and limits.
# Candidates, not yet run on a GPU: wide (4,096 envs x 32 steps, 131,072 frames a batch, four
# minibatches of 32,768, lr 1e-3) and narrow (2,048 x 16, 32,768 frames, lr 5e-4). Checkpoints restart
# the episodes, so they are spaced out; each validation flies 16 of the protocol's 30 s episodes.
wide="wide=num_envs=4096,rollout_steps=32,lr=1e-3,frames=60000000,eval_every=8000000,checkpoint_every=20000000"
narrow="narrow=num_envs=2048,rollout_steps=16,lr=5e-4,frames=30000000,eval_every=2000000,checkpoint_every=10000000"
recipes=${PPO_RECIPES:-"$wide $narrow"}
for recipe in $recipes; do
    name=${recipe%%=*}
    sets=()
    IFS=',' read -ra fields <<< "${recipe#*=}"
    for f in "${fields[@]}"; do [ -n "$f" ] && sets+=(--set "$f"); done
    start=$(date +%s)
    timeout "${PPO_S:-170}" $py -m falcon_rl.cli train ppo --task altitude --airframe volantex_ranger \
        --device cuda --seed "${SEED:-0}" --no-progress --logger csv --out "$out/ppo_$name" \
        --stop-when "survival>=1,acquisition>=0.95,rmse_m<=0.3" "${sets[@]}" 2>&1 | tee "$out/ppo_$name.txt"
    echo "ppo $name: whole command $(( $(date +%s) - start )) s" | tee -a "$out/ppo_$name.txt"
    snapshot
done
