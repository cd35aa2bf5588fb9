#!/usr/bin/env bash
# Installs what scripts/fuzz.sh needs beyond scripts/install_deps.sh: clang 14 with its runtime
# libraries (libFuzzer, ASan, UBSan, TSan) and llvm-symbolizer for readable stack traces. The main
# build and CI do not need them. Idempotent: apt is only touched when something is missing.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install_deps.sh >/dev/null
packages=(clang-14 libclang-rt-14-dev llvm-14)
source scripts/apt_packages.sh
mapfile -t missing < <(missing_packages "${packages[@]}")
if [ ${#missing[@]} -eq 0 ]; then exit 0; fi
apt_install install_fuzz_deps "${missing[@]}"
