#!/usr/bin/env bash
# Install everything pmsm2dof needs on a fresh Debian machine with Python >= 3.11:
# the Cortex-M cross compiler and emulator, clang for fuzzing, clang-format for the C
# style, Chromium for the browser test, then the package itself (editable) with its
# test, lint and docs extras and the extras of single commands (the tuner's server, Dask, the drive link).
set -euo pipefail
cd "$(dirname "$0")/.."

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
DEBS="gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm cmake clang clang-format libclang-rt-14-dev chromium"
missing=""
for deb in $DEBS; do
  dpkg-query -W -f='${Status}' "$deb" 2>/dev/null | grep -q "install ok installed" || missing="$missing $deb"
done
if [ -n "$missing" ]; then
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq $missing >/dev/null
fi

python3 -m pip install -q --upgrade pip
python3 -m pip install -q -e ".[test,lint,docs,tuner,dask,drive]"
