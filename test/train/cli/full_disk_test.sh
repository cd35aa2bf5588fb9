#!/usr/bin/env bash
# Every command that writes files, on a full disk: `lboost import colmap`, `map`, `vocab`, `train`,
# `export` and `localize` must fail with one line naming the file and the system's reason (exit 1),
# and leave no 0-byte or partial file at the final path and no temporary beside it; a folder the
# command created for its output (import's --out and the missing folder above it, train's run
# folder) is removed again.
#   full_disk_test.sh LBOOST TINY_DIR WORK
# TINY_DIR: the tiny rendered world (collection/ and map.h5, the lmb_tiny_world fixture).
# Two ways to fill the disk:
#   1. always: a file-size limit (`ulimit -f 0`, SIGXFSZ ignored): every write(2) that would grow a
#      file fails with EFBIG ("File too large"), exactly where a full disk fails with ENOSPC;
#   2. as root where mount namespaces work (`unshare -m`): a real 256 KB tmpfs, filled, in a private
#      mount namespace (nothing stays mounted if the test dies); ENOSPC ("No space left on device");
#      then tmpfs with room for half of map.h5 and of model.lbm, so that `map` and `export` run
#      out in the middle of their file. Skipped with a message otherwise.
set -uo pipefail
lboost=$1
tiny=$2
work=$3
fail() { echo "full_disk_test: FAIL: $*" >&2; exit 1; }
[ -f "$tiny/map.h5" ] || { echo "full_disk_test: SKIP: no tiny world at $tiny"; exit 77; }
rm -rf "$work"
mkdir -p "$work/inputs"
in=$work/inputs
collection=$tiny/collection

# Inputs, made with room on the disk: a vocabulary, a 4-round run and its model.lbm.
"$lboost" vocab --images "$collection/images" --words 16 --seed 7 --max-descriptors 20000 --out "$in/vocab.lbv" \
  > "$in/setup.log" 2>&1 || fail "vocab setup failed: $(tail -3 "$in/setup.log")"
"$lboost" train --map "$tiny/map.h5" --vocab "$in/vocab.lbv" --rounds 4 --dims-per-round 64 --out "$in/run" \
  >> "$in/setup.log" 2>&1 || fail "train setup failed: $(tail -3 "$in/setup.log")"
"$lboost" export --run "$in/run" --map "$tiny/map.h5" --vocab "$in/vocab.lbv" --out "$in/model.lbm" \
  >> "$in/setup.log" 2>&1 || fail "export setup failed: $(tail -3 "$in/setup.log")"

# The commands, each writing into $out (a folder on the full disk): "name|command|final path".
commands() {
  local out=$1
  echo "import colmap|import colmap --sparse $collection/sparse --images $collection/images --out $out/imported/collection|$out/imported/collection/sparse/cameras.txt"
  echo "map|map --collection $collection --out $out/map.h5 --threads 1|$out/map.h5"
  echo "vocab|vocab --images $collection/images --words 8 --max-descriptors 2000 --out $out/vocab.lbv|$out/vocab.lbv"
  echo "train|train --map $tiny/map.h5 --vocab $in/vocab.lbv --rounds 2 --dims-per-round 64 --out $out/run|$out/run/config.toml"
  echo "export|export --run $in/run --map $tiny/map.h5 --vocab $in/vocab.lbv --out $out/model.lbm|$out/model.lbm"
  echo "localize|localize --model $in/model.lbm --map $tiny/map.h5 --out $out/poses.json|$out/poses.json"
}

# check NAME STATUS ERRFILE FINAL OUT REASON: the outcome of one command.
check() {
  local name=$1 status=$2 err=$3 final=$4 out=$5 reason=$6
  [ "$status" -eq 1 ] || fail "$name: exit $status on a full disk, expected 1 ($(cat "$err"))"
  [ "$(wc -l < "$err")" -eq 1 ] || fail "$name: not one error line: $(cat "$err")"
  grep -q "^lboost $name: error: .*$reason" "$err" || fail "$name: no '$reason' in: $(cat "$err")"
  grep -qF "$out/" "$err" || fail "$name: the error does not name a file under $out: $(cat "$err")"
  [ ! -e "$final" ] || fail "$name: $final was left behind ($(stat -c %s "$final") bytes)"
  local left
  left=$(find "$out" \( -name '*.tmp-*' -o -type f -size 0 \) | head -n 3)
  [ -z "$left" ] || fail "$name: left behind: $left"
  [ ! -e "$out/run" ] || fail "$name: the refused run left its folder $out/run"
  # import creates its --out folder and the missing one above it: a failed import removes both.
  [ ! -e "$out/imported" ] || fail "$name: the failed import left $(find "$out/imported" | head -n 3)"
  echo "full_disk_test: $name: $(cat "$err")"
}

# 1. File-size limit.
out=$work/limit
mkdir -p "$out"
while IFS='|' read -r name args final; do
  status=0
  # stderr through a pipe: the limit applies to every regular file the command writes, a log too.
  # shellcheck disable=SC2086
  err=$( (trap '' XFSZ; ulimit -f 0; exec "$lboost" $args) 2>&1 > /dev/null ) || status=$?
  printf '%s\n' "$err" > "$work/stderr"
  check "$name" "$status" "$work/stderr" "$final" "$out" "File too large"
done < <(commands "$out")

# 2. A real full tmpfs.
if [ "$(id -u)" -eq 0 ] && unshare -m --propagation private true 2> /dev/null; then
  out=$work/tmpfs
  mkdir -p "$out"
  export lboost work out
  export -f commands check fail
  export collection tiny in
  unshare -m --propagation private bash -c '
    set -uo pipefail
    mount -t tmpfs -o size=256k lmb_full_disk "$out" || { echo "full_disk_test: SKIP tmpfs part: mount failed"; exit 0; }
    dd if=/dev/zero of="$out/.filler" bs=4k > /dev/null 2>&1
    while IFS="|" read -r name args final; do
      status=0
      # shellcheck disable=SC2086
      "$lboost" $args > "$work/stdout" 2> "$work/stderr" || status=$?
      check "$name" "$status" "$work/stderr" "$final" "$out" "No space left on device"
    done < <(commands "$out")
    # The disk fills up in the middle of the largest outputs: room for half of map.h5 or model.lbm.
    umount "$out"
    while IFS="|" read -r name args final; do
      case $name in map) size=$(stat -c %s "$tiny/map.h5") ;; export) size=$(stat -c %s "$in/model.lbm") ;; *) continue ;; esac
      mount -t tmpfs -o size=$(( size / 2 )) lmb_half_disk "$out"
      status=0
      # shellcheck disable=SC2086
      "$lboost" $args > "$work/stdout" 2> "$work/stderr" || status=$?
      check "$name" "$status" "$work/stderr" "$final" "$out" "No space left on device"
      umount "$out"
    done < <(commands "$out")
  ' || exit 1
else
  echo "full_disk_test: SKIP tmpfs part: needs root and mount namespaces (unshare -m); the file-size limit part ran"
fi
echo "full_disk_test: OK"
rm -rf "$work"
