#!/bin/sh
# Usage: make_case.sh LBOOST LMB_CROSS_CASE TINY_DIR OUT_DIR
# The x86 side of the cross-architecture comparison (ctest fixture infer/cross_arch_case_setup,
# scripts/cross_test.sh): trains a small model on the tiny world of TINY_DIR (collection/ and
# map.h5, made by the fixture train/export/tiny_world_setup) with the lboost pipeline's commands,
# exports it, and writes the case (model.lbm, frames.bin, expected.txt) into OUT_DIR with
# lmb_cross_case. Rebuilt on every run: the transcript is this build's.
set -eu
lboost=$1
case_tool=$2
tiny=$3
out=$4
work="$out/work"
rm -rf "$out"
mkdir -p "$work"
"$lboost" vocab --images "$tiny/collection/images" --out "$work/vocab.lbv" --words 16 --seed 7
"$lboost" train --map "$tiny/map.h5" --vocab "$work/vocab.lbv" --out "$work/run" --rounds 80 --top-k 400 --seed 3 --threads 2
"$lboost" export --run "$work/run" --map "$tiny/map.h5" --vocab "$work/vocab.lbv" --out "$work/model.lbm"
"$case_tool" "$tiny/map.h5" "$work/model.lbm" "$out"
