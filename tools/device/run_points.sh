#!/usr/bin/env bash
# On the borrowed machine, from the repository root (the device tool's `run`, carry [".device"]):
#   POINTS=0:3.2,9:3.6 SWEEP=model-ii-y POOL_S=530 bash .device/run_points.sh
# runs the prediction points with postprocess.point_pool, one process per physical core, for at
# most POOL_S seconds, then packs the finished points' summary/case/analysis.json into
# $OUT/receipts.tgz (unpack under results/prediction/runs/ here, then merge with
# prediction_study --seeds ... --frequencies ...).  The log is $OUT/pool.log.
set -u
T0=$(date +%s)
python3 -c "import zipfile; zipfile.ZipFile('.device/site.zip').extractall('/tmp/site')" || exit 3
export PYTHONPATH=/tmp/site:$PWD/.device/stubs:$PWD DEM_THREADS=1 PYTHONUNBUFFERED=1
lscpu > "$OUT/lscpu.txt" 2>&1; nproc; grep -m1 "model name" /proc/cpuinfo
python3 -c "import taichi, pydantic, numpy; print('numpy', numpy.__version__)" || exit 3
W=$(lscpu -p=CORE,SOCKET | grep -v '^#' | sort -u | wc -l); [ "$W" -gt 16 ] && W=16
echo "physical cores $W; setup $(($(date +%s) - T0)) s"
timeout "${POOL_S:-530}" python3 -m postprocess.point_pool --out results/prediction \
    --sweep "${SWEEP:-model-ii-y}" --points "$POINTS" --workers "$W" > "$OUT/pool.log" 2>&1
echo "pool exit $? after $(($(date +%s) - T0)) s"
python3 -m postprocess.point_pool --out results/prediction --sweep "${SWEEP:-model-ii-y}" \
    --points "$POINTS" --list > /tmp/list.txt
wc -l < /tmp/list.txt
[ -s /tmp/list.txt ] && tar czf "$OUT/receipts.tgz" -C results/prediction/runs -T /tmp/list.txt
grep -v Taichi "$OUT/pool.log" | tail -20
