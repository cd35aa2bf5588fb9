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

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#packages[@]} packages present"
  exit 0
fi

echo "install_deps: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install_deps: done"
