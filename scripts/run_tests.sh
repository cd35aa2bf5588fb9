#!/usr/bin/env bash
# The README's second command: installs what is missing, builds, and runs the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install_deps.sh
./scripts/build.sh
cd "${LMB_BUILD_DIR:-build}"
ctest --output-on-failure -j "${LMB_TEST_JOBS:-2}" "$@"
