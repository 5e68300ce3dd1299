#!/usr/bin/env bash
# Installs the Debian packages that the bpy wheel's shared libraries need, but only when
# something is missing (a fresh machine); prints nothing and does nothing otherwise.
set -eu
venv=${1:-.venv}
so=$(ls "$venv"/lib/python3*/site-packages/bpy/__init__.so 2>/dev/null | head -1 || true)
[ -n "$so" ] || { echo "ensure-system-deps: bpy is not installed in $venv" >&2; exit 1; }
missing=$(ldd "$so" 2>/dev/null | grep "not found" || true)
[ -z "$missing" ] && exit 0
echo "bpy needs system libraries that are missing:"; echo "$missing"
pkgs="libvulkan1 libx11-6 libxrender1 libxfixes3 libxi6 libxkbcommon0 libxext6 libsm6 libice6 \
libgl1 libegl1 libglx0 libxcb1 libxxf86vm1 libxau6 libxdmcp6 libuuid1 libbsd0"
sudo_cmd=""; [ "$(id -u)" = 0 ] || sudo_cmd="sudo"
export DEBIAN_FRONTEND=noninteractive
$sudo_cmd apt-get update -qq
$sudo_cmd apt-get install -y -qq --no-install-recommends $pkgs
still=$(ldd "$so" | grep "not found" || true)
[ -z "$still" ] || { echo "ensure-system-deps: still missing after install:"; echo "$still"; exit 1; } >&2
