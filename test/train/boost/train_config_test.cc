#include "train/boost/train_config.h"

#include <unistd.h>
#include <cmath>
#include <set>

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/file_io.h"

namespace lmb {
namespace {

TEST(TrainConfig, FileOverridesDefaultsAndRoundTrips) {
  TrainConfig c;
  apply_train_config_toml(
      "[boost]\nnum_rounds = 300\nexclusion_radius = 0.5\nscreening_step = true\n"
      "[training_set]\ntop_k_landmarks = 900\n[regions]\nnum_regions = 64\n[features]\nthreads = 2\n",
      "cfg.toml", &c);
  EXPECT_EQ(c.boost.num_rounds, 300);
  EXPECT_DOUBLE_EQ(c.boost.negatives.exclusion_radius, 0.5);
  EXPECT_TRUE(c.boost.screening.step);
  EXPECT_EQ(c.boost.dims_per_round, BoostOptions().dims_per_round);
  EXPECT_EQ(c.training_set.top_k_landmarks, 900);
  EXPECT_EQ(c.regions.num_regions, 64);
  EXPECT_EQ(c.feature_threads, 2);
  TrainConfig d;
  apply_train_config_toml(train_config_toml(c), "effective", &d);
  EXPECT_EQ(train_config_toml(d), train_config_toml(c));
  EXPECT_EQ(d.boost.num_rounds, 300);
  EXPECT_EQ(d.regions.num_regions, 64);
}

// A run's config.toml written before training_set.calibration_frames existed reads as 0 (that run
// held no frame out, and export must rebuild its training set); a user's config without the key
// gets the default, and a run's config with it keeps its value.
TEST(TrainConfig, ARunConfigWithoutTheCalibrationFramesKeyHeldNoneOut) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("lmb_run_config_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::filesystem::path old_run = dir / "old.toml", new_run = dir / "new.toml";
  write_file_atomically(old_run, "[training_set]\ntop_k_landmarks = 900\n");
  TrainConfig c;
  c.training_set.calibration_frames = 30;
  write_file_atomically(new_run, train_config_toml(c));
  EXPECT_EQ(read_train_config(old_run).training_set.calibration_frames, TrainingSetOptions().calibration_frames);
  EXPECT_GT(TrainingSetOptions().calibration_frames, 0);
  EXPECT_EQ(read_run_train_config(old_run).training_set.calibration_frames, 0);
  EXPECT_EQ(read_run_train_config(old_run).training_set.top_k_landmarks, 900);
  EXPECT_EQ(read_run_train_config(new_run).training_set.calibration_frames, 30);
  write_file_atomically(new_run, "[training_set]\ncalibration_frames = -1\n");
  EXPECT_THROW(read_run_train_config(new_run), Error);
  std::filesystem::remove_all(dir);
}

TEST(TrainConfig, AreaTableRoundTripsOnlyWhenSet) {
  TrainConfig c;
  EXPECT_EQ(train_config_toml(c).find("[area]"), std::string::npos);  // other runs' configs unchanged
  c.area.file = "/runs/areas.txt";
  c.area.id = 3;
  c.area.landmarks = 7311;
  c.area.landmarks_hash = 0x00ab00cd00ef0012ull;
  const std::string text = train_config_toml(c);
  EXPECT_NE(text.find("[area]"), std::string::npos) << text;
  EXPECT_NE(text.find("landmarks_hash = '00ab00cd00ef0012'"), std::string::npos) << text;
  TrainConfig d;
  apply_train_config_toml(text, "config.toml", &d);
  d.check();
  EXPECT_EQ(d.area.file, c.area.file);
  EXPECT_EQ(d.area.id, 3);
  EXPECT_EQ(d.area.landmarks, 7311);
  EXPECT_EQ(d.area.landmarks_hash, c.area.landmarks_hash);
  EXPECT_EQ(train_config_toml(d), text);
  auto message = [](const std::string& toml) {
    TrainConfig e;
    try {
      apply_train_config_toml(toml, "cfg.toml", &e);
    } catch (const Error& err) {
      return std::string(err.what());
    }
    return std::string("no error");
  };
  const std::string full = "[area]\nfile = 'a.txt'\nid = 1\nlandmarks = 5\nlandmarks_hash = '0000000000000001'\n";
  EXPECT_EQ(message(full), "no error");
  EXPECT_EQ(message("[area]\nfile = 'a.txt'\nid = 1\n"),
            "cfg.toml: [area] needs file, id, landmarks and landmarks_hash");
  EXPECT_EQ(message(full + "extra = 1\n"), "cfg.toml: unknown key area.extra");
  EXPECT_EQ(message("[area]\nfile = 'a.txt'\nid = -1\nlandmarks = 5\nlandmarks_hash = '0000000000000001'\n"),
            "cfg.toml: area.id: -1 is out of range");
  EXPECT_EQ(message("[area]\nfile = 'a.txt'\nid = 1\nlandmarks = 5\nlandmarks_hash = 'xyz'\n"),
            "cfg.toml: area.landmarks_hash: expected 16 hex digits");
  EXPECT_EQ(message("[area]\nfile = ''\nid = 1\nlandmarks = 5\nlandmarks_hash = '0000000000000001'\n"),
            "cfg.toml: area.file: expected a non-empty string");
}

TEST(TrainConfig, AugmentTableIsWrittenOnlyWhenAugmenting) {
  TrainConfig c;
  EXPECT_EQ(train_config_toml(c).find("[augment]"), std::string::npos);  // earlier runs' configs unchanged
  apply_train_config_toml("[augment]\ncopies = 2\ndropout = 0.4\nrotation_deg = 3\n", "cfg.toml", &c);
  c.check();
  EXPECT_EQ(c.augment.copies, 2);
  EXPECT_DOUBLE_EQ(c.augment.dropout, 0.4);
  EXPECT_DOUBLE_EQ(c.augment.position_sigma, -1.0);  // measured on the map
  const std::string text = train_config_toml(c);
  EXPECT_NE(text.find("[augment]"), std::string::npos) << text;
  TrainConfig d;
  apply_train_config_toml(text, "config.toml", &d);
  EXPECT_EQ(train_config_toml(d), text);
  EXPECT_DOUBLE_EQ(d.augment.rotation_deg, 3.0);
  // -1 means "measured"; other negative values are refused.
  c.augment.scale_sigma = -0.5;
  try {
    c.check();
    FAIL() << "scale_sigma -0.5 accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("scale_sigma must be -1 (measured) or >= 0"), std::string::npos) << e.what();
  }
}

TEST(TrainConfig, RejectsUnknownKeysWrongTypesAndSyntax) {
  TrainConfig c;
  auto message = [&](const std::string& text) {
    try {
      apply_train_config_toml(text, "cfg.toml", &c);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("[boost]\nnum_round = 3\n").find("boost.num_round"), std::string::npos);
  EXPECT_NE(message("[bost]\n").find("[bost]"), std::string::npos);
  EXPECT_NE(message("[boost]\nnum_rounds = \"many\"\n").find("integer"), std::string::npos);
  EXPECT_NE(message("[boost]\nnum_rounds = 1e99\n").find("integer"), std::string::npos);
  // Regression (found by test/fuzz/fuzz_train_config under UBSan): a float beyond the int64 range
  // for an integer key was cast to int64 inside toml++ before any range check.
  EXPECT_EQ(message("[boost]\nnum_rounds = 1e37\n"), "cfg.toml: boost.num_rounds: expected an integer");
  EXPECT_NE(message("[boost]\nnum_rounds = 99999999999\n").find("out of range"), std::string::npos);
  EXPECT_NE(message("[boost\n").find("cfg.toml"), std::string::npos);
  TrainConfig zero;
  apply_train_config_toml("[boost]\nnum_rounds = 0\n", "cfg.toml", &zero);
  EXPECT_THROW(zero.check(), Error);
}

TEST(TrainConfig, SchemaNamesEveryKeyOnceAndWritesEachOne) {
  std::set<std::string> names;
  for (const ConfigKey& k : train_config_schema()) EXPECT_TRUE(names.insert(k.name()).second) << k.name();
  // The written config holds exactly the schema's keys: one "key = value" line each ([augment]
  // only when augment.copies > 0: AugmentTableIsWrittenOnlyWhenAugmenting).
  TrainConfig augmenting;
  augmenting.augment.copies = 1;
  const std::string text = train_config_toml(augmenting);
  size_t lines = 0;
  for (size_t at = 0; (at = text.find(" = ", at)) != std::string::npos; at += 3) ++lines;
  EXPECT_EQ(lines, names.size());
  EXPECT_EQ(describe_config_key("boost.num_rounds"), "M, shared stumps (rounds) (default 2000)");
  EXPECT_EQ(describe_config_key("boost.blocked_screening"),
            "screen eight dims per class-major pass (false: one column pass per dim) (default true)");
  EXPECT_THROW(describe_config_key("boost.nothing"), Error);
}

TEST(TrainConfig, EveryRangeIsCheckedAtItsEnds) {
  // For every bounded key: its ends as the range says (inside: accepted, outside: refused with the
  // key's name), from the defaults; [regions] keys are checked by ContextRegionOptions::check.
  int checked = 0;
  for (const ConfigKey& k : train_config_schema()) {
    if (k.range.unbounded()) continue;
    auto message = [&](double value) {
      TrainConfig c;
      std::visit([&](auto* v) { *v = static_cast<std::remove_pointer_t<decltype(v)>>(value); }, k.ref(c));
      try {
        c.check();
      } catch (const Error& e) {
        return std::string(e.what());
      }
      return std::string("no error");
    };
    const bool integer = [&] {
      TrainConfig c;
      return !std::holds_alternative<double*>(k.ref(c));
    }();
    const double step = integer ? 1.0 : 1e-9;
    if (std::isfinite(k.range.lo)) {
      const double outside = k.range.lo_open ? k.range.lo : k.range.lo - step;
      const double inside = k.range.lo_open ? k.range.lo + step : k.range.lo;
      EXPECT_NE(message(outside).find(k.key), std::string::npos) << k.name() << " = " << outside;
      if (k.name() != "boost.max_negatives_per_class") {  // also bounded by negatives_per_class
        EXPECT_EQ(message(inside), "no error") << k.name() << " = " << inside;
      }
      ++checked;
    }
    if (std::isfinite(k.range.hi)) {
      const double outside = k.range.hi_open ? k.range.hi : k.range.hi + step;
      EXPECT_NE(message(outside).find(k.key), std::string::npos) << k.name() << " = " << outside;
      EXPECT_EQ(message(k.range.hi_open ? k.range.hi - step : k.range.hi), "no error") << k.name();
    }
    if (!integer) {
      EXPECT_NE(message(std::nan("")).find(k.key), std::string::npos) << k.name() << " = NaN";
      if (k.range.hi_open) {
        EXPECT_NE(message(INFINITY).find(k.key), std::string::npos) << k.name() << " = inf";
      }
    }
  }
  EXPECT_GE(checked, 20);
}

// Every config that passes check() round-trips through the config.toml written for it; seeds
// above TOML's largest integer (`--seed -1` is 2^64 - 1) are refused.
TEST(TrainConfig, EveryCheckedConfigRoundTripsAndHugeSeedsAreRefused) {
  TrainConfig c;
  c.boost.seed = c.training_set.seed = c.regions.seed = 9223372036854775807ull;
  c.check();
  TrainConfig d;
  apply_train_config_toml(train_config_toml(c), "config.toml", &d);
  EXPECT_EQ(d.boost.seed, c.boost.seed);
  EXPECT_EQ(d.regions.seed, c.regions.seed);
  c.boost.seed = 18446744073709551615ull;
  try {
    c.check();
    FAIL() << "seed 2^64 - 1 accepted";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "config: boost.seed = 18446744073709551615 must be in 0..9223372036854775807");
  }
}

// A value error of a config file names the file as well as the key.
TEST(TrainConfig, ValueErrorsOfAFileNameTheFile) {
  const std::filesystem::path path =
      std::filesystem::temp_directory_path() / ("lmb_train_config_" + std::to_string(::getpid()) + ".toml");
  write_file_atomically(path, "[boost]\nnum_rounds = 0\n");
  try {
    read_train_config(path);
    FAIL() << "num_rounds = 0 accepted";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), path.string() + ": boost options: num_rounds must be >= 1, got 0");
  }
  std::filesystem::remove(path);
  try {
    read_train_config(path);
    FAIL() << "a missing file accepted";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), path.string() + ": cannot open file: No such file or directory");
  }
}

}  // namespace
}  // namespace lmb
