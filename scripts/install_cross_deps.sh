#!/usr/bin/env bash
# Installs what scripts/cross_test.sh needs to cross-build the inference library for another
# architecture and run its tests under qemu-user, from Debian's packages:
#   scripts/install_cross_deps.sh [aarch64]
# the cross toolchain (crossbuild-essential-arm64), qemu-user, and the target architecture's
# packages of what lmb_infer and its tests link (OpenGV, GoogleTest; Eigen and cereal are headers)
# through multiarch (dpkg --add-architecture arm64). Idempotent: apt is only touched when something
# is missing.
set -euo pipefail
arch=${1:-aarch64}
case "$arch" in
  aarch64) deb_arch=arm64 ;;
  *) echo "install_cross_deps: unsupported architecture '$arch' (supported: aarch64)" >&2; exit 2 ;;
esac

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive

packages=(
  "crossbuild-essential-$deb_arch" qemu-user
  cmake ninja-build pkg-config libeigen3-dev libcereal-dev
  "libopengv-dev:$deb_arch" "libgtest-dev:$deb_arch"
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install_cross_deps: all ${#packages[@]} packages for $deb_arch present"
  exit 0
fi

if ! dpkg --print-foreign-architectures | grep -qx "$deb_arch"; then
  echo "install_cross_deps: dpkg --add-architecture $deb_arch"
  $SUDO dpkg --add-architecture "$deb_arch"
fi
echo "install_cross_deps: installing ${missing[*]}"
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install_cross_deps: done"
