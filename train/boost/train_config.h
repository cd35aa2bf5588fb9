// The settings of `lboost train`: TOML config file <-> structs. The effective config (defaults,
// file, then flags) is written into the run directory as config.toml; the same text is what a
// checkpoint can hash to refuse a changed config.
//
// Tables: [training_set] (TrainingSetOptions), [boost] (BoostOptions), [regions]
// (ContextRegionOptions), [augment] (AugmentOptions; written only when copies > 0, so the configs
// and checkpoints of runs without augmentation are those of earlier versions), [features] threads, [checkpoint]
// minutes, interval, keep (train/checkpoint/checkpoint_h5.h; not compared on resume), and, for a run of one area only,
// [area] file, id, landmarks, landmarks_hash (AreaReference; outside the schema: not a number each). Every key is named
// once, in the schema (train_config_schema(), built from the options' own schemas in train/boost/boost_options.h),
// which reads, writes, checks and describes the config.
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "common/context_regions.h"
#include "train/boost/boost_options.h"
#include "train/boost/settings.h"

namespace lmb {

// The area a run trains (`lboost train --area FILE:ID`, docs/areas.md): its classes are exactly the
// area's landmarks instead of the top-K. Written as the [area] table of config.toml only when set
// (file non-empty), so the configs of other runs and their checkpoints are unchanged.
struct AreaReference {
  std::string file;             // the areas file (lboost areas), absolute; empty = no area
  int32_t id = -1;              // the area's id in it
  int64_t landmarks = 0;        // its landmark count, checked when the file is read again
  uint64_t landmarks_hash = 0;  // landmark_list_hash of its landmarks, checked likewise
  bool set() const { return !file.empty(); }
};

struct TrainConfig {
  TrainingSetOptions training_set;
  BoostOptions boost;
  ContextRegionOptions regions;
  AugmentOptions augment;  // [augment], written only when augment.copies > 0
  int feature_threads = 1;
  double checkpoint_minutes = 10.0;  // wall minutes between checkpoints (0 = none by time)
  int32_t checkpoint_interval = 0;   // rounds between checkpoints (0 = none by rounds)
  int32_t checkpoint_keep = 3;       // newest checkpoints kept
  AreaReference area;
  void check() const;  // every part's check() and seeds in 0..2^63-1; throws lmb::Error naming the field
};

// One key of the config file, [table] key.
struct ConfigKey {
  std::string table;
  std::string key;
  std::function<SettingRef(TrainConfig&)> ref;
  SettingRange range;  // checked by TrainConfig::check (the [regions] keys by ContextRegionOptions::check)
  std::string help;
  std::string name() const { return table + "." + key; }
};
// Every key of the config file.
const std::vector<ConfigKey>& train_config_schema();
// "<help> (default <value>)" of the key "table.key". Throws lmb::Error for an unknown key.
std::string describe_config_key(const std::string& name);

// Overrides the fields present in a TOML document. Throws lmb::Error naming `what`, the table and
// key on a parse error, an unknown table or key, or a value of the wrong type or range.
void apply_train_config_toml(const std::string& toml_text, const std::string& what, TrainConfig* config);
// The defaults overridden by the file, then check()ed; every error names the file.
TrainConfig read_train_config(const std::filesystem::path& path);
// A run's config.toml (RUN_DIR/config.toml, which `lboost train` writes with every key): as
// read_train_config, except that a key added after the run was trained takes the value that
// reproduces that run's training set: without training_set.calibration_frames, 0 (no frame was
// held out).
TrainConfig read_run_train_config(const std::filesystem::path& path);
// Every field, as TOML (round-trips through apply_train_config_toml).
std::string train_config_toml(const TrainConfig& config);

}  // namespace lmb
