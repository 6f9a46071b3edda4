# Sourced by the GPU scripts: `. benchmarks/gpu_setup.sh OUTDIR` sets $out (made) and $py (python from
# $PYTHON, default python3), unbuffers Python's output, and writes the GPU and the package versions to
# $out/gpu.txt (and the terminal).
out=$1
py=${PYTHON:-python3}
mkdir -p "$out"
export PYTHONUNBUFFERED=1
nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm --format=csv | tee "$out/gpu.txt"
$py -c "import torch, warp, torchrl, tensordict; warp.init(); print('torch', torch.__version__, 'warp',
warp.__version__, 'torchrl', torchrl.__version__, 'tensordict', tensordict.__version__)" 2>&1 | tee -a "$out/gpu.txt"
