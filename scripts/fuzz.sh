#!/usr/bin/env bash
# Fuzzes every parser of outside data (test/fuzz) with libFuzzer + ASan + UBSan:
#   scripts/fuzz.sh [seconds-per-target] [target ...]      (default 60 s, all targets)
#   LMB_FUZZ_PARALLEL=N runs N targets at a time (default 1); LMB_FUZZ_TIMEOUT=s is the time after
#   which one input counts as a hang (default 10 s; raise it on a machine that is busy).
# Builds with clang into ${LMB_FUZZ_BUILD_DIR:-build-fuzz} (only the fuzz targets and what they
# link; configured without MPI, which no parser needs), writes seed corpora with the project's own
# writers (make_fuzz_seeds), then runs each
# target for the given time on a corpus kept in <build>/corpus/<target> (it grows across runs).
# Inputs are at most 1 MB (-max_len); no allocation may exceed 256 MB (-malloc_limit_mb) and the
# whole process 512 MB (-rss_limit_mb: it includes ASan's shadow memory and quarantine, ~130 MB
# for the HDF5 targets before the first input);
# an input running over 10 s (LMB_FUZZ_TIMEOUT) is a hang. Any crash, sanitizer report, leak, OOM or hang fails the
# run; the input that caused it is kept in <build>/artifacts/<target>/. Prints per target the
# executions, time and result, and appends them to <build>/fuzz_runs.tsv.
# Needs clang-14 and libclang-rt-14-dev (scripts/install_fuzz_deps.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
seconds=${1:-60}
shift || true
all_targets=(model vocabulary map_h5 colmap_text colmap_binary train_config gravity trained_model checkpoint
             bundle_index area_file session_file)
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then targets=("${all_targets[@]}"); fi
build=${LMB_FUZZ_BUILD_DIR:-build-fuzz}
case "$build" in /*) ;; *) build="$root/$build" ;; esac

./scripts/install_fuzz_deps.sh
flags="-fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer"
generator=()
if command -v ninja >/dev/null 2>&1 && [ ! -f "$build/CMakeCache.txt" ]; then generator=(-G Ninja); fi
cmake -S . -B "$build" "${generator[@]}" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
  -DCMAKE_C_FLAGS="$flags" -DCMAKE_CXX_FLAGS="$flags" \
  -DLMB_FUZZ=ON -DLMB_BUILD_TESTS=OFF -DLMB_MPI=OFF >/dev/null
cmake --build "$build" -j "${LMB_JOBS:-$(nproc)}" --target make_fuzz_seeds \
  $(printf 'fuzz_%s ' "${targets[@]}")

export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:allocator_may_return_null=0:quarantine_size_mb=64}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
# Third-party leaks only, each documented in the file.
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$root/test/sanitizers/lsan.supp:print_suppressions=0}
seeds="$build/seeds"
rm -rf "$seeds"
"$build/test/fuzz/make_fuzz_seeds" "$seeds"

log="$build/fuzz_runs.tsv"
[ -f "$log" ] || printf 'date\ttarget\tseconds\texecutions\tcorpus\tresult\n' >"$log"

# Runs one target; writes "seconds executions corpus exit-code" to $build/result_<target>.
run_target() {
  local t=$1 corpus="$build/corpus/$1" artifacts="$build/artifacts/$1" out="$build/fuzz_$1.log"
  mkdir -p "$corpus" "$artifacts"
  cp -n "$seeds/$t"/* "$corpus"/ 2>/dev/null || true
  local start rc=0 execs hangs=0 mode=()
  touch "$build/start_$t"
  # The HDF5 readers run in fork mode and go on after a failing input: libhdf5 1.10.8 (Debian
  # bookworm) itself loops forever, overflows buffers and makes absurd allocations on some damaged
  # files, which no code of ours can prevent. Every input kept in the artifacts is replayed after
  # the run (triage below): a report whose top frames are in libhdf5 counts as a libhdf5 fault, any
  # other fails the run.
  case "$t" in map_h5|checkpoint) mode=(-fork=1 -ignore_timeouts=1 -ignore_ooms=1 -ignore_crashes=1) ;; esac
  start=$(date +%s)
  (cd "$build" && "$build/test/fuzz/fuzz_$t" "$corpus" -dict="$root/test/fuzz/lmb.dict" "${mode[@]}" \
     -max_total_time="$seconds" -max_len=1048576 -rss_limit_mb=512 -malloc_limit_mb=256 -timeout="${LMB_FUZZ_TIMEOUT:-10}" \
     -artifact_prefix="$artifacts/" -print_final_stats=1 >"$out" 2>&1) || rc=$?
  if [ ${#mode[@]} -gt 0 ]; then
    execs=$(sed -n 's/^#\([0-9]*\): cov.*/\1/p' "$out" | tail -1)
    # In fork mode libFuzzer exits with its last child's status (77 after any ignored crash), so
    # only the triage decides.
    rc=0
    # Triage: replay each kept input; hangs are not replayed (they would hang again).
    local a report ours=0
    for a in $(find "$artifacts" -type f -newer "$build/start_$t"); do
      case "$(basename "$a")" in timeout-*) hangs=$((hangs + 1)); continue ;; esac
      # An oom-* input is replayed with room (8 GB) under the 256 MB allocation limit: at 512 MB
      # the RSS limit may trip first (ASan's shadow of a huge malloc alone is 1/8 of its size),
      # and its report shows the live heap (libFuzzer's own buffers), not the failed allocation.
      local rss=512
      case "$(basename "$a")" in oom-*) rss=8192 ;; esac
      report=$(cd "$build" && timeout 120 "$build/test/fuzz/fuzz_$t" -rss_limit_mb=$rss -malloc_limit_mb=256 "$a" 2>&1 || true)
      echo "$report" | grep -q -E "ERROR: |^SUMMARY: " || continue  # does not fail on replay
      # The first stack frame past the sanitizer, libFuzzer, allocator and libc frames decides.
      if echo "$report" | grep -A40 -E "ERROR: " | grep -E "^ +#[0-9]+ " |
         grep -v -E "sanitizer|fuzzer::|asan|interceptor|malloc|calloc|realloc|operator new|libc\.so|nptl|raise|abort" |
         head -1 | grep -q libhdf5; then
        hangs=$((hangs + 1))
      else
        echo "fault not in libhdf5: $a" >>"$out"
        ours=$((ours + 1))
      fi
    done
    [ "$ours" -gt 0 ] && rc=1
  else
    execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$out" | tail -1)
  fi
  echo "$(( $(date +%s) - start )) ${execs:-0} $(ls "$corpus" | wc -l) $rc ${hangs:-0}" >"$build/result_$t"
}

# LMB_FUZZ_PARALLEL targets at a time (default 1).
parallel=${LMB_FUZZ_PARALLEL:-1}
for t in "${targets[@]}"; do
  while [ "$(jobs -rp | wc -l)" -ge "$parallel" ]; do wait -n || true; done
  run_target "$t" &
done
wait

failed=0
printf '%-15s %8s %12s %10s %8s  %s\n' target seconds executions exec/s corpus result
for t in "${targets[@]}"; do
  read -r elapsed execs corpus_size rc hangs <"$build/result_$t"
  result=ok
  [ "$hangs" -gt 0 ] && result="ok, $hangs inputs fault inside libhdf5 (see $build/artifacts/$t/)"
  if [ "$rc" -ne 0 ]; then
    result="FAIL (exit $rc, see $build/fuzz_$t.log and $build/artifacts/$t/)"
    failed=1
  fi
  printf '%-15s %8d %12d %10d %8d  %s\n' "$t" "$elapsed" "$execs" $(( execs / (elapsed > 0 ? elapsed : 1) )) \
    "$corpus_size" "$result"
  printf '%s\t%s\t%d\t%d\t%d\t%s\n' "$(date -u +%FT%TZ)" "$t" "$elapsed" "$execs" "$corpus_size" "$result" >>"$log"
done
exit $failed
