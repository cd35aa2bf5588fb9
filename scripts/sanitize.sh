#!/usr/bin/env bash
# Builds the whole project and test suite with AddressSanitizer + UndefinedBehaviorSanitizer (gcc,
# -O2 -g1 with assertions on) in ${LMB_SANITIZE_BUILD_DIR:-build-asan} and runs ctest there:
#   scripts/sanitize.sh [ctest args ...]
# LMB_SANITIZE_TARGETS="t1 t2 ..." builds only those targets (with a ctest -R filter on their tests:
# a full sanitized build takes hours on a busy 2-core machine); default: everything.
# Any sanitizer report fails its test (halt_on_error, -fno-sanitize-recover=all). The flags also go
# through CFLAGS/CXXFLAGS/LDFLAGS so the e2e consumer project that the suite builds is sanitized too.
# Suppressions (third-party false positives only): test/sanitizers/*.supp, each entry documented.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
build=${LMB_SANITIZE_BUILD_DIR:-build-asan}
./scripts/install_deps.sh

# EIGEN_MALLOC_ALREADY_ALIGNED=1: Eigen switches to its own over-aligned allocator when it sees
# __SANITIZE_ADDRESS__, while Debian's libopengv (not sanitized) uses plain malloc; a container OpenGV
# allocates and the project frees (p3p's solutions) then reads a header that isn't there. glibc's and
# ASan's malloc both align to 16 bytes, which is all Eigen needs here, so keep the system library's ABI.
flags="-fsanitize=address,undefined,float-cast-overflow -fno-sanitize-recover=all -fno-omit-frame-pointer -g1"
flags="$flags -DEIGEN_MALLOC_ALREADY_ALIGNED=1"
export CFLAGS="$flags" CXXFLAGS="$flags" LDFLAGS="-fsanitize=address,undefined,float-cast-overflow"
generator=()
if command -v ninja >/dev/null 2>&1 && [ ! -f "$build/CMakeCache.txt" ]; then generator=(-G Ninja); fi
cmake -S . -B "$build" "${generator[@]}" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_FLAGS="$flags" -DCMAKE_CXX_FLAGS="$flags" -DCMAKE_EXE_LINKER_FLAGS="$LDFLAGS" \
  -DCMAKE_SHARED_LINKER_FLAGS="$LDFLAGS" \
  -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O2" -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2" >/dev/null
targets=()
for t in ${LMB_SANITIZE_TARGETS:-}; do targets+=(--target "$t"); done
cmake --build "$build" -j "${LMB_JOBS:-$(nproc)}" "${targets[@]}"

export ASAN_OPTIONS="detect_leaks=1:halt_on_error=1:abort_on_error=0:strict_string_checks=1:detect_stack_use_after_return=1:check_initialization_order=1:suppressions=$root/test/sanitizers/asan.supp"
export LSAN_OPTIONS="suppressions=$root/test/sanitizers/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:suppressions=$root/test/sanitizers/ubsan.supp"
cd "$build"
ctest --output-on-failure -j "${LMB_TEST_JOBS:-2}" "$@"
