#!/usr/bin/env bash
# The measurements that need a many-core machine (issue 29), as one prepared script:
#   bench/many_core.sh OUT [scaling|rig|all]
# scaling: bench_threads.py (one channel, 1..N threads) on numba's omp layer, and a quick run
#          on its tbb layer where the tbb package is importable;
# rig:     `ig demo` and `ig latency` at the default rig size, threads from the cores, and
#          bench_wire.py (the worker -> compositor hop).
# Results go to OUT (threads.json, threads_tbb.json, demo_report.json, latency.json, wire.json,
# the log).
# The Python packages must be importable already (on a machine without registries: wheels
# installed with pip --target and put on PYTHONPATH by the caller).
set -u
OUT=${1:?OUT folder}
MODE=${2:-all}
mkdir -p "$OUT"
cd "$(dirname "$0")/.."
export PYTHONPATH=$PWD:$PWD/proto${PYTHONPATH:+:$PYTHONPATH}
export PYTHONUNBUFFERED=1
export IG_CACHE_DIR=${IG_CACHE_DIR:-/tmp/ig-cache}
PY=${PYTHON:-python3}
# numba's tbb layer loads libtbb.so.12 from the library path; a wheel installed with --target
# leaves it under the target's lib/.
for lib in $(find "${PIP_TARGET:-/tmp/site}" -name 'libtbb.so.12' 2>/dev/null | head -1); do
  export LD_LIBRARY_PATH=$(dirname "$lib")${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
done
{
  date -u; nproc; grep -m1 "model name" /proc/cpuinfo
  $PY -c "import numba, numpy, llvmlite, grpc, google.protobuf as p; print('numba', numba.__version__, 'llvmlite', llvmlite.__version__, 'numpy', numpy.__version__, 'grpcio', grpc.__version__, 'protobuf', p.__version__)"
  t0=$(date +%s)
  $PY -m services.cli compile --scene channel_worker/data/airfield_terrain.json 2>&1 | tail -3
  echo "compile: $(( $(date +%s) - t0 )) s"
  if [ "$MODE" = scaling ] || [ "$MODE" = all ]; then
    $PY bench/bench_threads.py --out "$OUT" --repeats "${REPEATS:-3}"
    if $PY -c "from numba.np.ufunc import tbbpool" 2>&1 | tail -1; then
      NUMBA_THREADING_LAYER=tbb $PY bench/bench_threads.py --quick --out "$OUT/tbb" \
        && mv "$OUT/tbb/threads.json" "$OUT/threads_tbb.json"; rm -rf "$OUT/tbb"
    else
      echo "numba's tbb layer is not available here: the omp layer alone was measured"
    fi
  fi
  if [ "$MODE" = rig ] || [ "$MODE" = all ]; then
    $PY -m services.cli demo --out /tmp/demo --record-every 0 --exr-every 0 --duration "${DEMO_S:-10}" \
      && cp /tmp/demo/latest/report.json "$OUT/demo_report.json"
    $PY -m services.cli latency --steps "${STEPS:-10}" --out "$OUT/latency.json" --work /tmp/latency
    $PY bench/bench_wire.py --repeats "${WIRE_FRAMES:-200}" --out "$OUT"
  fi
  date -u
} 2>&1 | tee "$OUT/many_core.log"
