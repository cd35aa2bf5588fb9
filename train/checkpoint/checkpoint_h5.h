// Training checkpoints: HDF5 files (serial library, written by rank 0) holding everything needed
// to continue a run bit for bit, in RUN_DIR/checkpoints/ckpt-RRRRRRR.h5 (RRRRRRR = rounds done).
// The format, dataset by dataset, and the resume rules: docs/checkpoint.md. This library
// (lmb_checkpoint) links HDF5 and the serial learner's types only, never MPI.
//
// Layout: root attributes format = "landmarkboost-checkpoint", format_version = 2, rounds,
// seed (int64 bit pattern of boost.seed), ranks (that wrote it, information only), config_hash
// (hex FNV-1a of the compared settings), data (the training data source), crc32 (of every
// dataset's bytes in the order below) and complete = 1 (written last);
// datasets /config (the effective config TOML), /data_source, /model (the BoostModel, cereal
// portable binary), /feature_space (common/feature_space.h: the regions, vocabulary and map the
// stumps were trained on, cereal portable binary), /learner/{entry_sample, entry_code, entry_weight, tracked_samples,
// tracked_scores, class_offset, negative_unit, last_validation} and attributes /learner weight_exponent,
// num_validation_rows (train/boost/learner_state.h).
//
// Writes: the file is built in memory and written by the project's atomic writer (temporary file
// beside the target, fsync, rename, fsync of the folder); a crash or a full disk never leaves a
// partial ckpt-*.h5. Reading checks format, version, completeness, shapes and the
// CRC before returning anything.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "common/error.h"
#include "common/feature_space.h"
#include "train/boost/learner_state.h"

namespace lmb {

inline constexpr const char* kCheckpointFormat = "landmarkboost-checkpoint";
inline constexpr int kCheckpointVersion = 2;  // 1: no feature space (refused)

struct Checkpoint {
  int32_t rounds = 0;          // rounds done
  uint64_t seed = 0;           // boost.seed
  int32_t ranks = 1;           // ranks of the run that wrote it
  std::string config;          // the effective config TOML of the run
  std::string data;            // the training data source (map path or synthetic preset)
  FeatureSpace feature_space;  // what the stumps were trained on
  LearnerState state;
};

// A checkpoint that is whole but cannot be resumed by this build (another format version): never
// skipped for an older checkpoint, the run is refused instead.
class CheckpointVersionError : public Error {
 public:
  using Error::Error;
};

// Throws lmb::Error naming the file on any I/O failure.
void write_checkpoint(const std::filesystem::path& path, const Checkpoint& checkpoint);
// Throws lmb::Error "<path>: <field>: <reason>" for a missing, torn, incomplete or corrupt file,
// another format, or a CRC mismatch; CheckpointVersionError for another format version.
Checkpoint read_checkpoint(const std::filesystem::path& path);

// The settings that must match to resume: every "table.key" of a train config TOML except
// boost.num_rounds (a run may be extended), features.threads and [checkpoint] (they do not change
// the model).
uint64_t config_hash(const std::string& config_toml);
// Empty when the compared settings agree, else the first differing one:
// "boost.dims_per_round (checkpoint 500, now 400)".
std::string config_difference(const std::string& checkpoint_toml, const std::string& current_toml);

// The checkpoints of a run: RUN_DIR/checkpoints.
class CheckpointDir {
 public:
  explicit CheckpointDir(const std::filesystem::path& run_dir);
  const std::filesystem::path& folder() const { return folder_; }
  std::filesystem::path path_for(int32_t rounds) const;
  // ckpt-*.h5 files, newest (most rounds) first.
  std::vector<std::filesystem::path> list() const;
  // The newest checkpoint that reads back whole; each newer one that fails is passed to
  // `on_skip` (path, reason). nullopt when none is valid. A checkpoint of another format version
  // is not skipped: its CheckpointVersionError propagates.
  std::optional<Checkpoint> newest_valid(
      const std::function<void(const std::filesystem::path&, const std::string&)>& on_skip) const;
  // Writes ckpt-<rounds>.h5 and deletes all but the newest `keep` (keep >= 1).
  std::filesystem::path write(const Checkpoint& checkpoint, int keep) const;

 private:
  std::filesystem::path folder_;
};

}  // namespace lmb
