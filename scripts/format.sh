#!/usr/bin/env bash
# The project's C/C++ style (.clang-format: Google's, 120 columns), applied by clang-format 14
# (Debian bookworm's; other versions break lines differently, so the check pins it):
#   scripts/format.sh           rewrites every tracked .c/.cc/.h file in place
#   scripts/format.sh --check   changes nothing; lists the files that differ and exits 1 (CI)
# Installs clang-format-14 when it is missing (idempotent).
set -euo pipefail
cd "$(dirname "$0")/.."
check=0
case "${1:-}" in
  --check) check=1 ;;
  "") ;;
  *) sed -n '2,6p' "$0"; exit 2 ;;
esac
if ! command -v clang-format-14 >/dev/null 2>&1; then
  echo "format: installing clang-format-14"
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends clang-format-14 >/dev/null
fi
mapfile -t files < <(git ls-files '*.c' '*.cc' '*.h')
if [ "$check" -eq 0 ]; then
  clang-format-14 -i "${files[@]}"
  exit 0
fi
bad=()
for f in "${files[@]}"; do
  if ! clang-format-14 --dry-run --Werror "$f" >/dev/null 2>&1; then bad+=("$f"); fi
done
if [ ${#bad[@]} -gt 0 ]; then
  printf 'format: %d file(s) differ from .clang-format (run scripts/format.sh):\n' "${#bad[@]}"
  printf '  %s\n' "${bad[@]}"
  exit 1
fi
echo "format: ${#files[@]} files match .clang-format"
