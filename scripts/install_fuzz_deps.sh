#!/usr/bin/env bash
# Installs what scripts/fuzz.sh needs beyond scripts/install_deps.sh: clang 14 with its runtime
# libraries (libFuzzer, ASan, UBSan, TSan) and llvm-symbolizer for readable stack traces. The main
# build and CI do not need them. Idempotent: apt is only touched when something is missing.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install_deps.sh >/dev/null
packages=(clang-14 libclang-rt-14-dev llvm-14)
missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
if [ ${#missing[@]} -eq 0 ]; then exit 0; fi
echo "install_fuzz_deps: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
