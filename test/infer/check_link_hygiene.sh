#!/bin/sh
# Usage: check_link_hygiene.sh <shared library>
# Fails when the library needs MPI, HDF5 or OpenCV, directly (readelf -d NEEDED entries) or through
# its dependencies (ldd), or when it exports symbols that are not its API (lmb::detail, OpenGV,
# Eigen). The ctest infer/link_hygiene_selftest runs it on an OpenCV library and expects failure.
set -u
lib="$1"
forbidden='mpi|hdf5|opencv'
status=0

if [ ! -f "$lib" ]; then
  echo "FAIL: no such library: $lib"
  exit 1
fi

needed=$(readelf -d "$lib" | sed -n 's/.*(NEEDED).*\[\(.*\)\]/\1/p')
echo "NEEDED entries of $lib:"
echo "$needed" | sed 's/^/  /'
bad=$(echo "$needed" | grep -i -E "$forbidden")
if [ -n "$bad" ]; then
  echo "FAIL: NEEDED entries match '$forbidden':"
  echo "$bad" | sed 's/^/  /'
  status=1
fi

# LMB_LDD: the command that lists a library's dependencies (a cross build: the target's loader
# under qemu, --list); default ldd.
ldd_command=${LMB_LDD:-ldd}
# shellcheck disable=SC2086  # the command is words
deps=$($ldd_command "$lib") || { echo "FAIL: $ldd_command failed on $lib"; exit 1; }
echo "$ldd_command $lib:"
echo "$deps" | sed 's/^/  /'
bad=$(echo "$deps" | grep -i -E "$forbidden")
if [ -n "$bad" ]; then
  echo "FAIL: transitive dependencies match '$forbidden':"
  echo "$bad" | sed 's/^/  /'
  status=1
fi
bad=$(echo "$deps" | grep 'not found')
if [ -n "$bad" ]; then
  echo "FAIL: unresolved dependencies:"
  echo "$bad" | sed 's/^/  /'
  status=1
fi

# Exported (defined, dynamic) symbols: only the API. Internals, OpenGV and Eigen code linked into
# the library must stay hidden.
exported=$(nm -D -C --defined-only "$lib" | cut -d' ' -f3-)
bad=$(echo "$exported" | grep -E '^(lmb::detail::|opengv::|Eigen::)')
if [ -n "$bad" ]; then
  echo "FAIL: internal symbols are exported:"
  echo "$bad" | head -20 | sed 's/^/  /'
  status=1
fi

[ $status -eq 0 ] && echo "OK: $lib links no MPI, HDF5 or OpenCV and exports only its API"
exit $status
