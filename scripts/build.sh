#!/usr/bin/env bash
# Configures and builds LandmarkBoost (Release) into ${LMB_BUILD_DIR:-build}.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${LMB_BUILD_DIR:-build}
jobs=${LMB_JOBS:-$(nproc)}
generator=()
if command -v ninja >/dev/null 2>&1 && [ ! -f "$build_dir/CMakeCache.txt" ]; then generator=(-G Ninja); fi
cmake -S . -B "$build_dir" "${generator[@]}" -DCMAKE_BUILD_TYPE=Release ${LMB_CMAKE_ARGS:-} >/dev/null
cmake --build "$build_dir" -j "$jobs"
