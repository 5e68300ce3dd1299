#!/bin/bash
# Pack what `make bench-gpu` needs for a machine that has a GPU but no Blender and no network (the
# workplace's lent device machine): the venv's Python, the venv (bpy, numpy, OpenEXR, OpenCV,
# matplotlib, pytest) trimmed of what a Linux GPU run never loads, the X11 client libraries bpy
# links, and a Cycles CUDA kernel for the GPU's architecture where the bpy wheel ships none.
#
# Why the kernel: bpy 5.2's wheel has CUDA cubins for sm_50-86 and sm_120 only. On an H100/H200
# (sm_90) Cycles falls back to the compute_75 PTX and the driver JIT-compiles it on the first
# render, which outlasts a short device lease (docs/decisions.md, "The GPU benchmark needs a
# Cycles kernel for the GPU it runs on"). ptxas (NVIDIA's pip wheel, runs on any x86-64 CPU)
# compiles the same PTX into the missing cubin here, once, and the device never JITs.
#
# Usage: tools/device_bundle.sh [SM]   (SM default 90; run `make venv` first)
# Output: .gpuchunk/p0 .. pN (parts of at most 58 MiB, so each fits one call's 64 MiB working
# tree beside the repo) and .gpuchunk/final (tools/device_bench.sh). Then, with the device tool,
# in quick succession (a machine goes back after 30 s idle):
#   run(command="mkdir -p /tmp/plc && cp .gpuchunk/pK/* /tmp/plc/", carry=[".gpuchunk/pK"])   K = 0..N-1
#   run(command="cp .gpuchunk/pN/* /tmp/plc/ && bash .gpuchunk/final/device_bench.sh",
#       carry=[".gpuchunk/pN", ".gpuchunk/final"], timeout_s=600)
# About six parts, ~5 s of device time each after the machine's start.
set -euo pipefail
SM=${1:-90}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
VENV=$ROOT/.venv
WORK=${TMPDIR:-/tmp}/platelight-device-bundle
STAGE=$WORK/stage
NVCC_WHEEL=nvidia-cuda-nvcc-cu12==12.9.86      # its ptxas reads Blender's PTX 7.4 and targets sm_90/100/120
SP=$(echo "$VENV"/lib/python3.*/site-packages)
BPY=$SP/bpy
RELEASE=$(basename "$(ls -d "$BPY"/[0-9]*.[0-9]*)")
CYCLES_LIB=$BPY/$RELEASE/scripts/addons_core/cycles/lib
test -d "$BPY" || { echo "No bpy in $VENV: run \`make venv\` first." >&2; exit 1; }

rm -rf "$STAGE" && mkdir -p "$STAGE"/py "$STAGE"/venv "$STAGE"/syslib "$WORK"
# The interpreter the venv points at, and where it must appear on the device
PREFIX=$(dirname "$(dirname "$(readlink -f "$VENV"/bin/python3)")")
echo "$PREFIX" > "$STAGE"/PY_PREFIX
cp -a "$PREFIX"/. "$STAGE"/py/
PYLIB=$(echo "$STAGE"/py/lib/python3.*)
rm -rf "$PYLIB"/{test,idlelib,tkinter,ensurepip,turtledemo,config-*} "$PYLIB"/site-packages/* "$STAGE"/py/lib/libpython*.a
cp -a "$VENV"/. "$STAGE"/venv/
find "$STAGE" -name __pycache__ -type d -prune -exec rm -rf {} +

# What a Linux GPU bench never loads: other vendors' kernels, USD's Python, big unused add-ons,
# the farm tools' packages
SSP=$(echo "$STAGE"/venv/lib/python3.*/site-packages)
SBPY=$SSP/bpy
(cd "$SBPY/$RELEASE/scripts/addons_core/cycles/lib" && ls | grep -v -e '^kernel_compute_' -e '^kernel_optix' -e '^kernel_sm_' | xargs -r rm -f)
rm -f "$SBPY"/lib/libOpenImageDenoise_device_hip.so* "$SBPY"/lib/libOpenImageDenoise_device_sycl.so*
rm -rf "$SBPY/$RELEASE"/python/lib/python3.*/site-packages/pxr "$SBPY/$RELEASE"/scripts/addons_core/rigify
rm -rf "$SSP"/openjd* "$SSP"/pydantic* "$SSP"/Cython "$SSP"/pyximport

# The missing cubin, compiled from the newest PTX Blender ships
if [ ! -f "$CYCLES_LIB/kernel_sm_$SM.cubin.zst" ]; then
  PTX=$(ls "$CYCLES_LIB"/kernel_compute_*.ptx.zst | sort -V | tail -1)
  CUBIN=$WORK/kernel_sm_$SM.cubin
  if [ ! -f "$CUBIN" ]; then
    python3 -m pip download -q --no-deps --only-binary=:all: --platform manylinux2014_x86_64 \
      --platform manylinux_2_12_x86_64 -d "$WORK" "$NVCC_WHEEL"
    (cd "$WORK" && unzip -o -q nvidia_cuda_nvcc_cu12-*.whl 'nvidia/cuda_nvcc/bin/ptxas')
    zstd -d -q -c "$PTX" > "$WORK"/kernel.ptx
    echo "ptxas: $(basename "$PTX") -> sm_$SM (tens of minutes on 2 cores) ..."
    "$WORK"/nvidia/cuda_nvcc/bin/ptxas --split-compile 0 -arch=sm_$SM -O3 "$WORK"/kernel.ptx -o "$CUBIN.tmp"
    mv "$CUBIN.tmp" "$CUBIN"
  fi
  zstd -q -19 -f "$CUBIN" -o "$SBPY/$RELEASE/scripts/addons_core/cycles/lib/kernel_sm_$SM.cubin.zst"
fi

# X11/GL client libraries bpy links that a GPU server image may lack (the device runner puts
# them on the library path only when ldd finds some missing)
ldd "$BPY"/__init__.so | awk '$3 ~ /^\/(usr\/)?lib/ {print $3}' | while read -r lib; do
  case $(basename "$lib") in libc.so*|libm.so*|libdl.so*|librt.so*|libpthread.so*|libutil.so*|ld-linux*|libstdc++*|libgcc_s*) ;;
    *) cp -L "$lib" "$STAGE"/syslib/ ;; esac
done

echo "packing $(du -sh "$STAGE" | cut -f1) ..."
rm -rf "$ROOT"/.gpuchunk && mkdir -p "$ROOT"/.gpuchunk/final
grep -qx '/.gpuchunk/' "$ROOT"/.git/info/exclude 2>/dev/null || echo '/.gpuchunk/' >> "$ROOT"/.git/info/exclude
tar -C "$STAGE" -cf - . | xz -8 -T0 | split -b 60817408 -d -a 1 - "$WORK"/part_
for part in "$WORK"/part_*; do
  k=${part##*_}; mkdir -p "$ROOT"/.gpuchunk/p"$k" && mv "$part" "$ROOT"/.gpuchunk/p"$k"/
done
cp "$ROOT"/tools/device_bench.sh "$ROOT"/.gpuchunk/final/
ls -d "$ROOT"/.gpuchunk/* && du -sh "$ROOT"/.gpuchunk
