#!/usr/bin/env bash
# Installs gcmap's dependencies from Debian 12 packages and builds it into build/.
# Idempotent. Usage: ./scripts/setup.sh [extra cmake arguments, e.g. -DGCMAP_CUDA=OFF]
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(build-essential cmake pkg-config libeigen3-dev libtbb-dev libnanoflann-dev
  libcli11-dev libyaml-cpp-dev libspdlog-dev libgtest-dev libbenchmark-dev
  libcairo2-dev libpng-dev libjs-three chromium-headless-shell
  libzstd-dev liblz4-dev libbz2-dev libsqlite3-dev libproj-dev proj-bin
  pybind11-dev python3-dev python3-numpy python3-pytest
  clang libclang-rt-14-dev libsuitesparse-dev libopenblas0-pthread)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  sudo_cmd=()
  [ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
  "${sudo_cmd[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

cmake -S . -B build -DCMAKE_BUILD_TYPE=Release "$@"
cmake --build build -j "$(nproc)"
