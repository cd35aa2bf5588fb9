#!/usr/bin/env bash
# Installs LandmarkBoost's build and run dependencies from Debian's packages.
# Idempotent: packages already present are left alone; apt is only touched when something is missing.
set -euo pipefail

packages=(
  build-essential cmake pkg-config ninja-build bc
  libeigen3-dev libopencv-dev libopengv-dev libcereal-dev
  libhdf5-dev hdf5-tools
  libopenmpi-dev openmpi-bin
  libgtest-dev libgmock-dev
  libcli11-dev libspdlog-dev nlohmann-json3-dev libtomlplusplus-dev
  libfaiss-dev
  python3-matplotlib python3-numpy
  python3-dev pybind11-dev python3-pytest python3-pil
)

source "$(dirname "$0")/apt_packages.sh"
mapfile -t missing < <(missing_packages "${packages[@]}")
if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#packages[@]} packages present"
  exit 0
fi
apt_install install_deps "${missing[@]}"
echo "install_deps: done"
