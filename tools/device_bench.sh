#!/bin/bash
# Device side of tools/device_bundle.sh: unpack the carried parts (/tmp/plc/part_*), put the
# Python and the venv where the venv expects them, check that Cycles renders on the GPU within a
# minute, then run the composite benchmark at 960x540 on the GPU into $OUT/bench (rows written
# after each row, so a run cut short still brings back what it measured).
# Environment: BACKEND (CUDA), SCENES (diffuse,mirror,glossy), CATCHER (4,16,64,256),
# ROUTES_A / A_S (Cycles routes and their seconds), ROUTES_B / B_S (EEVEE routes and seconds).
set -u
T0=$(date +%s); say() { echo "[$(( $(date +%s) - T0 ))s] $*"; }
OUT=${OUT:-/tmp/platelight-out}
mkdir -p /tmp/plb "$OUT"/bench
cat /tmp/plc/part_* | python3 -c "import sys, tarfile; tarfile.open(fileobj=sys.stdin.buffer, mode='r|xz').extractall('/tmp/plb')" \
  || { say "The carried parts do not unpack: carry every part of one tools/device_bundle.sh run."; exit 3; }
say unpacked
PREFIX=$(cat /tmp/plb/PY_PREFIX)
[ -e "$PREFIX" ] || { mkdir -p "$(dirname "$PREFIX")" && ln -s /tmp/plb/py "$PREFIX"; }   # a bare machine lacks it
rm -rf .venv && ln -sfn /tmp/plb/venv .venv
BPY_SO=$(echo .venv/lib/python3.*/site-packages/bpy/__init__.so)
export LD_LIBRARY_PATH=/usr/local/nvidia/lib64${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
if ldd "$BPY_SO" | grep -q "not found"; then
  export LD_LIBRARY_PATH=$LD_LIBRARY_PATH:/tmp/plb/syslib; say "using the carried X11/GL libraries"
fi
for f in /usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json /usr/share/glvnd/egl_vendor.d/10_nvidia.json; do
  [ -f "$f" ] && export __EGL_VENDOR_LIBRARY_FILENAMES=$f && break
done
nvidia-smi --query-gpu=name,driver_version,compute_cap --format=csv,noheader
export PYTHONUNBUFFERED=1 BACKEND=${BACKEND:-CUDA}
# A minute for a 64x64 render: longer means the driver is compiling Cycles' kernels from PTX
timeout 60 .venv/bin/python - <<'PY' || { say "Cycles did not render 64x64 on the GPU within 60 s: no cubin for this GPU? (tools/device_bundle.sh SM)"; exit 4; }
import os, time, bpy
prefs = bpy.context.preferences.addons["cycles"].preferences
prefs.compute_device_type = os.environ["BACKEND"]
prefs.get_devices()
for d in prefs.devices:
    d.use = d.type == os.environ["BACKEND"]
scene = bpy.context.scene
scene.render.engine, scene.cycles.device, scene.cycles.samples = "CYCLES", "GPU", 4
scene.render.resolution_x = scene.render.resolution_y = 64
scene.render.filepath = "/tmp/smoke.png"
t = time.time()
bpy.ops.render.render(write_still=True)
print("smoke render", [d.name for d in prefs.devices if d.use], f"{time.time() - t:.1f} s")
PY
export PLATELIGHT_BENCH_DEVICE=GPU PLATELIGHT_BENCH_SIZE=960x540 PLATELIGHT_BENCH_GPU_BACKEND=$BACKEND \
  PLATELIGHT_BENCH_SCENES=${SCENES:-diffuse,mirror,glossy} PLATELIGHT_BENCH_CATCHER_SPP=${CATCHER:-4,16,64,256}
PLATELIGHT_BENCH_ROUTES=${ROUTES_A:-sbrdf,sbrdf_baked,cycles} timeout "${A_S:-300}" \
  .venv/bin/python tests/bench/run_all.py --out "$OUT"/bench --only composite > "$OUT"/bench_a.log 2>&1
say "Cycles routes: exit $?"; grep -E "^\{|s$|Error|Traceback" "$OUT"/bench_a.log | tail -40
PLATELIGHT_BENCH_KEEP_ROWS=1 PLATELIGHT_BENCH_ROUTES=${ROUTES_B:-sbrdf_eevee,sbrdf_eevee_baked} timeout "${B_S:-150}" \
  .venv/bin/python tests/bench/run_all.py --out "$OUT"/bench --only composite > "$OUT"/bench_b.log 2>&1
say "EEVEE routes: exit $?"; grep -E "^\{|s$|Error|Traceback" "$OUT"/bench_b.log | tail -20
ls -la "$OUT"/bench
