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

source "$(dirname "$0")/apt_packages.sh"
packages=(
  "crossbuild-essential-$deb_arch" qemu-user
  cmake ninja-build pkg-config libeigen3-dev libcereal-dev
  "libopengv-dev:$deb_arch" "libgtest-dev:$deb_arch"
)
mapfile -t missing < <(missing_packages "${packages[@]}")
if [ ${#missing[@]} -eq 0 ]; then
  echo "install_cross_deps: all ${#packages[@]} packages for $deb_arch present"
  exit 0
fi
if ! dpkg --print-foreign-architectures | grep -qx "$deb_arch"; then
  echo "install_cross_deps: dpkg --add-architecture $deb_arch"
  if [ "$(id -u)" -ne 0 ]; then sudo dpkg --add-architecture "$deb_arch"; else dpkg --add-architecture "$deb_arch"; fi
fi
apt_install install_cross_deps "${missing[@]}"
echo "install_cross_deps: done"
