#!/usr/bin/env bash
# On the borrowed machine, from the repository root (the device tool's `run`, carry [".device"]):
#   POINTS=0:3.2,9:3.6 SWEEP=model-ii-y POOL_S=530 bash .device/run_points.sh
# runs the prediction points with studies.prediction.pool, one process per physical core, for at
# most POOL_S seconds (then SIGTERM; SIGKILL 40 s later), and packs the finished points'
# summary/case/analysis/truncated-rows JSON into $OUT/receipts.tgz every 30 s while they run and
# once more at the end: a call cut short by the tool's own timeout still brings back every point
# it finished.  Unpack it under results/prediction/runs/ here, then merge with `python -m studies prediction`
# --seeds ... --frequencies ....  The log is $OUT/pool.log.  Give the call a timeout_s of at
# least POOL_S + 60.
set -u
T0=$(date +%s)
python3 -c "import zipfile; zipfile.ZipFile('.device/site.zip').extractall('/tmp/site')" || exit 3
export PYTHONPATH=/tmp/site:$PWD/.device/stubs:$PWD DEM_THREADS=1 PYTHONUNBUFFERED=1
lscpu > "$OUT/lscpu.txt" 2>&1; nproc; grep -m1 "model name" /proc/cpuinfo
python3 -c "import taichi, pydantic, numpy; print('numpy', numpy.__version__)" || exit 3
W=$(lscpu -p=CORE,SOCKET | grep -v '^#' | sort -u | wc -l); [ "$W" -gt 16 ] && W=16
echo "physical cores $W; setup $(($(date +%s) - T0)) s"
ARGS=(--out results/prediction --sweep "${SWEEP:-model-ii-y}" --points "$POINTS")
pack() {     # receipts.tgz replaced whole (a rename inside $OUT), never left half written
    python3 -m studies.prediction.pool "${ARGS[@]}" --list > /tmp/list.txt 2>/dev/null || return 0
    [ -s /tmp/list.txt ] || return 0
    tar czf "$OUT/receipts.partial.tgz" -C results/prediction/runs -T /tmp/list.txt &&
        mv -f "$OUT/receipts.partial.tgz" "$OUT/receipts.tgz"
}
# the packer's sleep is killed with it and holds no output pipe (the call ends when the pool does)
( trap 'kill $SL 2>/dev/null; exit 0' TERM
  while :; do sleep 30 & SL=$!; wait $SL; pack; done ) > /dev/null 2>&1 & PACKER=$!
timeout -k 40 "${POOL_S:-530}" python3 -m studies.prediction.pool "${ARGS[@]}" --workers "$W" \
    > "$OUT/pool.log" 2>&1
echo "pool exit $? after $(($(date +%s) - T0)) s"
kill "$PACKER" 2>/dev/null; wait "$PACKER" 2>/dev/null
pack
[ -f "$OUT/receipts.tgz" ] && tar tzf "$OUT/receipts.tgz" | grep -c summary.json
grep -v -e Taichi -e image.py -e "Save a field" "$OUT/pool.log" | tail -20
echo "done after $(($(date +%s) - T0)) s"
