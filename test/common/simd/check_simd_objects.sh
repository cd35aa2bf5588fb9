#!/bin/sh
# Usage: check_simd_objects.sh <object file>...
# The SIMD kernel files compiled with ISA flags (names ending in _avx2 or _avx512) may define only
# local code and their own global kernels: a weak or unique symbol (an inline or template
# function emitted out of line, COMDAT) could be picked by the linker for callers in baseline
# code and run AVX2 or AVX-512 instructions on a CPU without them (common/simd/simd_level.h).
# Other object files are ignored. The ctest common/simd/object_hygiene_selftest runs it on an
# object that breaks the rule.
set -u
status=0
checked=0
# ctest passes $<TARGET_OBJECTS:...> as one ';'-separated argument per target.
objects=$(printf '%s\n' "$@" | tr ';' '\n')
for obj in $objects; do
  case "$obj" in
    *_avx2.cc.o|*_avx512.cc.o|*_avx2.o|*_avx512.o) ;;
    *) continue ;;
  esac
  checked=$((checked + 1))
  # Defined symbols whose type is not local code or data (t, r, d, b) or a global kernel (T).
  bad=$(nm -C --defined-only "$obj" | awk '$2 !~ /^[tTrRdDbB]$/ { print }')
  if [ -n "$bad" ]; then
    echo "FAIL: $obj defines weak or unique symbols (inline or template code compiled with ISA flags):"
    echo "$bad" | head -20 | sed 's/^/  /'
    status=1
  fi
  bad=$(nm -C --defined-only "$obj" | awk '$2 == "T" { $1 = ""; $2 = ""; print }' | grep -v -E '^ *lmb::detail::[a-z0-9_]+_avx(2|512)\(')
  if [ -n "$bad" ]; then
    echo "FAIL: $obj defines global symbols other than its kernels (lmb::detail::*_avx2 / *_avx512):"
    echo "$bad" | head -20 | sed 's/^/  /'
    status=1
  fi
done
if [ "$checked" -eq 0 ]; then
  echo "FAIL: no SIMD kernel object among the arguments"
  exit 1
fi
[ $status -eq 0 ] && echo "OK: $checked SIMD kernel objects define only local code and their kernels"
exit $status
