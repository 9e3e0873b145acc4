#!/usr/bin/env bash
# Shared set-up for scripts/demo.sh and scripts/test.sh: installs what a fresh Debian 12
# machine lacks (apt-get when root; otherwise prints the exact command and stops),
# then configures and builds subslam (Release) and its Python module in build/. Fast when
# nothing changed.
#
# Environment: BUILD_DIR (default build), BUILD_TYPE (default Release),
#              CMAKE_ARGS (extra configure arguments), JOBS (default nproc).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build}"
BUILD_TYPE="${BUILD_TYPE:-Release}"
JOBS="${JOBS:-$(nproc)}"

PACKAGES=(cmake g++ make ccache libceres-dev libeigen3-dev libsuitesparse-dev libabsl-dev
          libgtest-dev libbenchmark-dev libboost-dev nlohmann-json3-dev libtbb-dev python3-matplotlib
          python3-dev pybind11-dev python3-pybind11 python3-numpy python3-pytest python3-nbconvert
          python3-ipykernel clang-format)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
if ((${#missing[@]})); then
  if [[ $(id -u) -eq 0 ]]; then
    echo "setup: installing ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -q
    apt-get install -y -q --no-install-recommends "${missing[@]}"
  else
    echo "setup: missing packages; run as root:" >&2
    echo "  sudo apt-get update && sudo apt-get install -y ${missing[*]}" >&2
    exit 1
  fi
fi

# The Python module is built too (python/, docs/python.md); a build directory configured
# without it is reconfigured once.
if [[ ! -f "$BUILD_DIR/CMakeCache.txt" ]] || ! grep -q '^SUBSLAM_BUILD_PYTHON:BOOL=ON' "$BUILD_DIR/CMakeCache.txt"; then
  cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE="$BUILD_TYPE" -DSUBSLAM_BUILD_PYTHON=ON ${CMAKE_ARGS:-}
fi
cmake --build "$BUILD_DIR" -j "$JOBS"
