#!/usr/bin/env bash
# The standing GPU checklist (../shared/gpu/CHECKLIST.md) as one device call: CUDA-only
# tests, the speed benchmark at paper sizes, then paper-scale walker_walk runs for a fixed
# time. Every step has its own time limit; results land in $OUT (a few flat files).
#
# Set-up here first (../shared/gpu/README.md): the simulator bundle in .gpu, the GL loaders
# in .gl, both in .git/info/exclude. Then, from the device tool:
#   run(command="bash scripts/gpu_checklist.sh", carry=[".gpu", ".gl"], timeout_s=...)
# Dry run on a CPU: DRY=1 OUT=/tmp/gpu-dry bash scripts/gpu_checklist.sh
set -u
OUT=${OUT:-/tmp/gpu-out}
T_TESTS=${T_TESTS:-120}   # seconds for the CUDA-only tests
T_BENCH=${T_BENCH:-150}   # seconds for seqrank bench
T_LEARN=${T_LEARN:-210}   # seconds for the paper-scale runs (stopped with SIGTERM, resumable)
SCHEMES=${SCHEMES:-"root sequential pairwise"}
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1 OMP_NUM_THREADS=2
PY=${PY:-python3}
DEVICE=cuda
SCALE=paper
if [ -n "${DRY:-}" ]; then
    DEVICE=cpu
    SCALE=small
    T_LEARN=${T_LEARN_DRY:-60}
    PY=${PY_DRY:-.venv/bin/python}
    export PYTHONPATH=$PWD/src
else
    for f in .gl/*.deb; do dpkg -x "$f" /; done
    ldconfig
    export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
    export MUJOCO_GL=egl
    mkdir -p /tmp/sim && tar -xJf .gpu/sim312.tar.xz -C /tmp/sim
    export PYTHONPATH=/tmp/sim:$PWD/src
fi
stamp() { echo "=== $(date -u +%H:%M:%S) $*"; }

{
    stamp "device"
    nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv 2>&1
    $PY -c "import torch, sys; print('python', sys.version.split()[0], 'torch', torch.__version__,
'cuda', torch.version.cuda, torch.cuda.get_device_name() if torch.cuda.is_available() else 'no cuda')"
    nproc
} > "$OUT/device.txt" 2>&1
cat "$OUT/device.txt"

stamp "1. CUDA-only tests"
if [ -z "${DRY:-}" ]; then
    timeout "$T_TESTS" $PY -m pytest -q -rA -p no:cacheprovider -m gpu \
        tests/agents/test_sac_paths.py > "$OUT/pytest.txt" 2>&1
    echo "pytest exit $?" | tee -a "$OUT/pytest.txt"
    tail -5 "$OUT/pytest.txt"
fi

stamp "2. seqrank bench (paper sizes, every precision)"
if [ -n "${DRY:-}" ]; then
    bench_args=(--repeats 1 --updates 5 --loop-steps 300 --reward-epochs 1 --precisions fp32)
else
    bench_args=(--repeats 2 --updates 200 --loop-steps 1000 --reward-epochs 5)
fi
timeout "$T_BENCH" $PY -m seqrank bench --device $DEVICE --scale $SCALE "${bench_args[@]}" \
    --out "$OUT/bench-paper" > "$OUT/bench-log.txt" 2>&1
echo "bench exit $?"
tail -30 "$OUT/bench-log.txt"

stamp "3. paper-scale walker_walk runs, $T_LEARN s, side by side on the one GPU"
runs=/tmp/gpu-runs
rm -rf "$runs"
for scheme in $SCHEMES; do
    timeout -k 40 -s TERM "$T_LEARN" $PY -m seqrank train --task walker_walk --scheme "$scheme" \
        --scale $SCALE --device $DEVICE --eval-every 10000 --checkpoint-every 10000 \
        --out "$runs/$scheme" --quiet > "$runs-$scheme.log" 2>&1 &
done
timeout -k 40 -s TERM "$T_LEARN" $PY -m seqrank train --task walker_walk --reward true \
    --scale $SCALE --device $DEVICE --eval-every 10000 --checkpoint-every 10000 \
    --out "$runs/true-reward" --quiet > "$runs-true-reward.log" 2>&1 &
wait
for log in "$runs"-*.log; do echo "--- $log"; tail -15 "$log"; done
stamp "done"
tar -czf "$OUT/runs.tar.gz" -C /tmp --exclude='checkpoint*' --exclude='*.pt' \
    gpu-runs $(cd /tmp && ls gpu-runs-*.log)
