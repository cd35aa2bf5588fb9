#!/usr/bin/env bash
# Cross-builds the inference library and its tests for another architecture and runs them under
# qemu-user, then checks that the other architecture localizes like this one:
#   scripts/cross_test.sh [aarch64]
# 1. scripts/install_cross_deps.sh: the cross toolchain, qemu-user and the target's packages of
#    OpenGV and GoogleTest (multiarch); idempotent.
# 2. The native build (${LMB_BUILD_DIR:-build}, scripts/build.sh's) builds lboost and
#    lmb_cross_case and writes a case: a model trained on the tiny rendered world, its query frames
#    and this build's transcript of localizing them (test/infer/cross_arch/make_case.sh).
# 3. The cross build (${LMB_CROSS_BUILD_DIR:-build-<arch>}, LMB_INFER_ONLY: lmb_common, lmb_infer
#    and their tests) with cmake/toolchains/<arch>-linux-gnu.cmake.
# 4. ctest there, every test under qemu (NEON kernels against the generic ones, the whole
#    inference suite, infer/cross_arch_test replaying the native case); then the kernel tests and
#    the replay again with LMB_SIMD=generic.
# Extra arguments go to the first ctest run.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
arch=${1:-aarch64}
[ $# -gt 0 ] && shift
case "$arch" in
  aarch64) ;;
  *) echo "cross_test: unsupported architecture '$arch' (supported: aarch64)" >&2; exit 2 ;;
esac
start=$(date +%s)
./scripts/install_cross_deps.sh "$arch"
command -v "qemu-$arch" >/dev/null || { echo "cross_test: qemu-$arch not found" >&2; exit 1; }

# 2. The native side: lboost, lmb_cross_case and the tiny world, then the case.
native=${LMB_BUILD_DIR:-build}
./scripts/install_deps.sh
./scripts/build.sh
tiny="$root/$native/test/train/export/tiny_world"
if [ ! -f "$tiny/map.h5" ]; then
  "$native/train/lboost" world --preset tiny --seed 1 --out "$tiny/collection"
  "$native/train/lboost" map --collection "$tiny/collection" --out "$tiny/map.h5"
fi
case_dir="$root/$native/cross_case_$arch"
sh test/infer/cross_arch/make_case.sh "$native/train/lboost" "$native/test/infer/lmb_cross_case" "$tiny" "$case_dir"

# 3. The cross build.
cross=${LMB_CROSS_BUILD_DIR:-build-$arch}
generator=()
if command -v ninja >/dev/null 2>&1 && [ ! -f "$cross/CMakeCache.txt" ]; then generator=(-G Ninja); fi
cmake -S . -B "$cross" "${generator[@]}" -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_TOOLCHAIN_FILE="$root/cmake/toolchains/$arch-linux-gnu.cmake" \
  -DLMB_INFER_ONLY=ON -DLMB_CROSS_CASE_DIR="$case_dir" ${LMB_CMAKE_ARGS:-} >/dev/null
cmake --build "$cross" -j "${LMB_JOBS:-$(nproc)}"
file -L "$cross/infer/liblmb_infer.so" | grep -q "ARM aarch64" || { echo "cross_test: liblmb_infer.so is not an $arch library" >&2; exit 1; }

# 4. The tests under qemu: all of them at the CPU's level (NEON), then the kernels' tests and the
# replay on the generic kernels.
# Some qemu-user builds cannot start a thread or fork (Debian bookworm's qemu 7.2 on recent host
# kernels: the new thread or child spins forever). A probe program finds out; when it hangs, the
# test cases that start threads (named *Thread*) are skipped, with a line saying so, and
# everything else runs.
probe_dir="$cross/qemu_probe"
mkdir -p "$probe_dir"
printf '%s\n' '#include <pthread.h>' 'static void* run(void* a) { return a; }' \
  'int main(void) { pthread_t t; if (pthread_create(&t, 0, run, 0)) return 1; return pthread_join(t, 0); }' \
  > "$probe_dir/threads.c"
"$arch-linux-gnu-gcc" -pthread "$probe_dir/threads.c" -o "$probe_dir/threads"
if ! timeout 20 "qemu-$arch" -L "/usr/$arch-linux-gnu" "$probe_dir/threads"; then
  echo "cross_test: this qemu-$arch ($("qemu-$arch" --version | head -1)) cannot run a program that starts a" \
    "thread (the probe hung or failed); skipping the test cases that start threads (GTEST_FILTER=-*Thread*)"
  export GTEST_FILTER='-*Thread*'
fi
cd "$cross"
ctest --output-on-failure --timeout 1800 -j "${LMB_TEST_JOBS:-2}" "$@"
LMB_SIMD=generic ctest --output-on-failure --timeout 1800 -j "${LMB_TEST_JOBS:-2}" -R 'simd|cross_arch|classifier_test'
echo "cross_test $arch: passed in $(( $(date +%s) - start )) s; transcripts in $case_dir"
