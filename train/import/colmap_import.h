// `lboost import colmap`: a COLMAP sparse model (text or binary) + its image folder -> a
// collection with a map/query split (images renamed map/<name> and query/<name>, linked, never
// copied) and optional per-image gravity. 2D and 3D points are dropped: the mapper re-detects
// keypoints and triangulates from the poses.
#pragma once

#include <filesystem>
#include <string>

namespace lmb {

struct ColmapImportOptions {
  std::filesystem::path sparse_dir;  // cameras/images(/points3D) .txt or .bin
  std::filesystem::path image_dir;   // the folder COLMAP's image names are relative to
  std::filesystem::path out_dir;
  // The split, over the images sorted by name (see train/import/split_rule.h; list entries are
  // image names or their file names; time rules are not available).
  std::string split = "every:3";
  std::filesystem::path gravity_file;  // optional: gravity.txt in the model's image names
  std::string up;                      // optional: the model's world up axis, e.g. "+z"
  bool overwrite = false;
  void check() const;  // throws lmb::Error naming the option
};

struct ColmapImportStats {
  int images = 0;
  int map_frames = 0;
  int query_frames = 0;
  bool binary = false;      // the model was read from .bin files
  bool has_gravity = false;
};

// Throws lmb::Error (one line naming file, record and reason) for malformed models, missing or
// unreadable images, gravity files that do not match the model, or an unusable split.
ColmapImportStats import_colmap(const ColmapImportOptions& options);

}  // namespace lmb
