#!/usr/bin/env bash
# Builds the inference library and its tests with ThreadSanitizer (clang 14, -O1 -g) in
# ${LMB_TSAN_BUILD_DIR:-build-tsan} and runs them: the concurrency tests (a Localizer and the pose
# estimator shared by 4 threads, the C API's per-thread errors, a bundle's areas scored on a thread
# pool) and the classifier's tests.
#   scripts/tsan.sh [ctest args ...]
# A data race fails the test (halt_on_error). Suppressions: test/sanitizers/tsan.supp.
# clang, not gcc: with gcc 12's shared libtsan.so.2 every test linking liblmb_infer.so crashed inside
# libtsan during dynamic relocation, before main (Debian bookworm, kernel 6.x); clang links its TSan
# runtime statically. clang comes from scripts/install_fuzz_deps.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
build=${LMB_TSAN_BUILD_DIR:-build-tsan}
./scripts/install_fuzz_deps.sh

flags="-fsanitize=thread -fno-omit-frame-pointer -g"
export CFLAGS="$flags" CXXFLAGS="$flags" LDFLAGS="-fsanitize=thread"
generator=()
if command -v ninja >/dev/null 2>&1 && [ ! -f "$build/CMakeCache.txt" ]; then generator=(-G Ninja); fi
cmake -S . -B "$build" "${generator[@]}" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
  -DCMAKE_C_FLAGS="$flags" -DCMAKE_CXX_FLAGS="$flags" -DCMAKE_EXE_LINKER_FLAGS="$LDFLAGS" \
  -DCMAKE_SHARED_LINKER_FLAGS="$LDFLAGS" \
  -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1" -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1" >/dev/null
# Not model_test: it replaces operator new to count allocations, which clang's static TSan
# runtime also defines (and it runs no threads).
tests=(localizer_test pose_estimator_test c_api_test classifier_test area_bundle_test)
cmake --build "$build" -j "${LMB_JOBS:-$(nproc)}" --target $(printf 'infer_%s ' "${tests[@]}")

export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$root/test/sanitizers/tsan.supp"
cd "$build"
ctest --output-on-failure -j "${LMB_TEST_JOBS:-1}" -R "^infer/($(IFS='|'; echo "${tests[*]}"))\$" "$@"
