#!/usr/bin/env bash
# The batched engine's GPU check on a borrowed machine (tools/device/README.md), from the repository root:
#   device run, carry [".device"] (bash tools/device/make_bundle.sh first), timeout_s 570:
#   R=8 CYCLES=10 KS=1,16,64,100 bash tools/device/gpu_batch_check.sh
# Everything it measures lands in $OUT (gpu.jsonl, points_gpu.json, points_cpu.json,
# cpu_lone.jsonl, log.txt); tools/device/gpu_batch_check.py says what each part is.
set -u
python3 -c "import zipfile; zipfile.ZipFile('.device/site.zip').extractall('/tmp/site')" || exit 3
export PYTHONPATH=/tmp/site:$PWD/.device/stubs:$PWD PYTHONUNBUFFERED=1
# Taichi's offline cache of an earlier call (its ticache.tgz copied to .device/): no recompiling
[ -f .device/ticache.tgz ] && tar xzf .device/ticache.tgz -C /tmp
export TI_OFFLINE_CACHE_FILE_PATH=/tmp/ticache
{ nvidia-smi -L; nproc; grep -m1 "model name" /proc/cpuinfo; } 2>&1 | tee "$OUT/machine.txt"
nvidia-smi --query-gpu=timestamp,memory.used,utilization.gpu --format=csv -l 2 > "$OUT/smi.csv" 2>&1 &
python3 tools/device/gpu_batch_check.py 2>&1 | tee "$OUT/log.txt"
kill %1 2>/dev/null
tar czf "$OUT/ticache.tgz" -C /tmp ticache
