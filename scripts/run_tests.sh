#!/usr/bin/env bash
# The README's second command: installs what is missing, builds with warnings as errors
# (-DLMB_WERROR=ON, as CI does; LMB_WERROR=OFF builds without), and runs the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install_deps.sh
LMB_CMAKE_ARGS="-DLMB_WERROR=${LMB_WERROR:-ON} ${LMB_CMAKE_ARGS:-}" ./scripts/build.sh
cd "${LMB_BUILD_DIR:-build}"
ctest --output-on-failure -j "${LMB_TEST_JOBS:-2}" "$@"
