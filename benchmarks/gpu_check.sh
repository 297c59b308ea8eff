#!/usr/bin/env bash
# The prepared GPU check of issue 24: one command, <= 8 minutes on one GPU.
#
#   benchmarks/gpu_check.sh OUT_DIR            # on a GPU machine: tests + benchmarks on the GPU
#   benchmarks/gpu_check.sh OUT_DIR --cpu      # the same on CPU (what the test suite runs, with --tiny)
#   benchmarks/gpu_check.sh OUT_DIR --cpu --tiny
#
# 1. installs what it needs from wheels carried along (WHEELS=folder of .whl files, default
#    ./wheels if present; no network): jax[cuda12] plugin wheels + the project, --no-index;
# 2. records the device (nvidia-smi, jax.devices()) in OUT_DIR/device.json;
# 3. runs the ops and methods test subset with JAX on the GPU (JMESHTEX_TEST_PLATFORMS=cuda; the
#    root conftest.py must honour it, else the tests run on CPU and device.json says so);
# 4. runs the field-conv, face-conv, FLDM denoiser and surface-CNN benchmarks through the runner
#    (python -m benchmarks), each into OUT_DIR/<name>/sweep.json, and copies them to
#    OUT_DIR/<name>_gpu.json (or _cpu.json) for benchmarks/results/.
# Exit status: non-zero when a step failed (every step runs; OUT_DIR/summary.txt lists them).
set -uo pipefail

usage() { echo "usage: $0 OUT_DIR [--cpu] [--tiny]" >&2; exit 2; }
[ $# -ge 1 ] || usage
OUT=$1; shift
CPU=0; TINY=0
for arg in "$@"; do
  case "$arg" in
    --cpu) CPU=1 ;;
    --tiny) TINY=1 ;;
    *) usage ;;
  esac
done
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT"
export PYTHONPATH="$ROOT${PYTHONPATH:+:$PYTHONPATH}"
mkdir -p "$OUT"; OUT=$(cd "$OUT" && pwd)
PY=${PYTHON:-python}
[ -x "$ROOT/.venv/bin/python" ] && [ -z "${PYTHON:-}" ] && PY="$ROOT/.venv/bin/python"
START=$(date +%s)
BUDGET=${GPU_CHECK_BUDGET_S:-470}   # seconds for the whole check (8 min, less a margin)
FAILED=()
: > "$OUT/summary.txt"
note() { echo "$*" | tee -a "$OUT/summary.txt"; }
left() { echo $(( BUDGET - ($(date +%s) - START) )); }
step() {  # step NAME SECONDS CMD...: run with a timeout capped by what is left of the budget
  local name=$1 limit=$2; shift 2
  local rest; rest=$(left)
  [ "$rest" -lt "$limit" ] && limit=$rest
  if [ "$limit" -le 5 ]; then note "SKIP $name (budget spent)"; FAILED+=("$name"); return; fi
  local t0; t0=$(date +%s)
  timeout "$limit" "$@" > "$OUT/$name.log" 2>&1
  local rc=$?
  note "$( [ $rc -eq 0 ] && echo OK || echo "FAIL($rc)" ) $name $(( $(date +%s) - t0 )) s"
  [ $rc -eq 0 ] || FAILED+=("$name")
}

# 1. wheels carried along (no index, no network)
WHEELS=${WHEELS:-$ROOT/wheels}
if [ -d "$WHEELS" ]; then
  # every carried wheel (jax-cuda12-plugin, jax-cuda12-pjrt, the nvidia-* libraries, test deps),
  # resolved among themselves; jmeshtex itself runs from this checkout (PYTHONPATH)
  step install 150 "$PY" -m pip install --no-index --find-links "$WHEELS" -q "$WHEELS"/*.whl
fi

if [ $CPU -eq 1 ]; then
  export JAX_PLATFORMS=cpu JMESHTEX_TEST_PLATFORMS=cpu SUFFIX=cpu
else
  export JAX_PLATFORMS=cuda JMESHTEX_TEST_PLATFORMS=cuda SUFFIX=gpu
  export XLA_PYTHON_CLIENT_PREALLOCATE=false   # benchmarks measure their own peaks
fi

# 2. the device
step device 60 "$PY" - "$OUT/device.json" <<'PYEOF'
import json, os, pathlib, subprocess, sys
import jax
info = {"backend": jax.default_backend(), "devices": [str(d) for d in jax.devices()],
        "device_kind": jax.devices()[0].device_kind, "jax": jax.__version__,
        "tests_on_device": "JMESHTEX_TEST_PLATFORMS" in pathlib.Path("conftest.py").read_text()}
try:
    info["nvidia_smi"] = subprocess.run(["nvidia-smi", "--query-gpu=name,memory.total,driver_version",
                                         "--format=csv,noheader"], capture_output=True, text=True, timeout=20).stdout.strip()
except (OSError, subprocess.SubprocessError):
    info["nvidia_smi"] = None
pathlib.Path(sys.argv[1]).write_text(json.dumps(info, indent=1))
print(json.dumps(info))
want = os.environ["JAX_PLATFORMS"].replace("cuda", "gpu")
sys.exit(0 if info["backend"] == want else f"backend {info['backend']}, wanted {want}")
PYEOF

# 3. the ops and methods test subset
if [ $TINY -eq 1 ]; then
  TESTS=${GPU_CHECK_TESTS:-jmeshtex/parallel}
else
  TESTS=${GPU_CHECK_TESTS:-tests/ops tests/nn tests/fl tests/fldm tests/surfacecnn tests/dgts tests/parallel}
fi
# not the slow tests (learning checks: minutes each, device-independent); xdist workers share the GPU
XDIST=""
[ $CPU -eq 0 ] && "$PY" -c "import xdist" 2>/dev/null && XDIST="-n 4"
# shellcheck disable=SC2086
step tests 240 "$PY" -m pytest -q -p no:cacheprovider -m "not slow" $XDIST $TESTS

# 4. the benchmarks (sizes per script, in its own unit), through the runner
if [ $TINY -eq 1 ]; then
  BENCHES=("ops_field_conv --quick" "ops_face_conv --quick")
else
  BENCHES=("ops_field_conv --sizes 5000 30000 80000" "ops_face_conv --sizes 5 6 7"
           "fldm_step --sizes 5000 30000 --presets paper" "surfacecnn --sizes 256 512")
fi
for spec in "${BENCHES[@]}"; do
  name=${spec%% *}
  # shellcheck disable=SC2086
  step "bench_$name" 150 "$PY" -m benchmarks run $spec --out "$OUT/$name" --timeout 150
  [ -f "$OUT/$name/sweep.json" ] && cp "$OUT/$name/sweep.json" "$OUT/${name}_${SUFFIX}.json"
done

note "total $(( $(date +%s) - START )) s; failed: ${FAILED[*]:-none}"
[ ${#FAILED[@]} -eq 0 ]
