# The stages after the map, shared by the job scripts (sourced, not run):
#   vocab world images -> vocab -> inspect -> train -> export -> localize -> eval.
# The caller sets lboost, out (holding map.h5), threads, here (the repository), defines stage(), and
# may set default_train_args, train_threads and train_cmd (the train command line, launcher
# included; default: one process); stages whose output exists are kept. LMB_TRAIN_ARGS, LMB_LOCALIZE_ARGS and
# LMB_EVAL_ARGS override the train, localize and eval flags.
model_stages() {
  if [ -z "${train_cmd+x}" ]; then train_cmd=("$lboost" train); fi
  if [ ! -d "$out/vocab_world" ]; then
    # The vocabulary is trained on images that are not the map's: another seed of the world.
    stage "vocab images: an unrelated world (seed 1001)"
    "$lboost" world --preset tiny --seed 1001 --out "$out/vocab_world" --threads "$threads"
  fi
  if [ ! -f "$out/vocab.lbv" ]; then
    stage "vocab: 16 binary words by k-majority"
    "$lboost" vocab --images "$out/vocab_world/images" --out "$out/vocab.lbv" --words 16 --seed 7
  fi
  stage "inspect: the map and its descriptor aliasing"
  "$lboost" inspect "$out/map.h5" --threads "$threads" | tee "$out/inspect.txt"
  if [ ! -f "$out/run/model.bin" ]; then
    stage "train: shared-stump classifier (${train_cmd[*]})"
    "${train_cmd[@]}" --map "$out/map.h5" --vocab "$out/vocab.lbv" --out "$out/run" \
      --threads "${train_threads:-$threads}" ${LMB_TRAIN_ARGS:-${default_train_args:---rounds 300}}
  fi
  if [ ! -f "$out/model.lbm" ]; then
    stage "export: model.lbm"
    "$lboost" export --run "$out/run" --map "$out/map.h5" --vocab "$out/vocab.lbv" --out "$out/model.lbm"
  fi
  stage "localize: the query frames (background rejected: a match must beat the background class)"
  "$lboost" localize --model "$out/model.lbm" --map "$out/map.h5" --out "$out/poses.json" \
    --threads "$threads" ${LMB_LOCALIZE_ARGS:-}
  stage "eval: LandmarkBoost and the baselines on the query frames (report.json, plots)"
  LBOOST="$lboost" "$here/jobs/eval.sh" "$out" ${LMB_EVAL_ARGS:-}
}
