// `lboost import colmap`: a COLMAP sparse model (text or binary) + its image folder -> a
// collection with a map/query split (images renamed map/<name> and query/<name>, linked, never
// copied) and optional per-image gravity. 2D and 3D points are dropped: the mapper re-detects
// keypoints and triangulates from the poses.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/io/colmap_model.h"
#include "common/rigid3.h"

namespace lmb {

struct ColmapImportOptions {
  std::filesystem::path sparse_dir;  // cameras/images(/points3D) .txt or .bin
  std::filesystem::path image_dir;   // the folder COLMAP's image names are relative to
  std::filesystem::path out_dir;
  // The split, over the images sorted by name (see train/import/split_rule.h; list entries are
  // image names or their file names; time rules are not available).
  std::string split = "every:3";
  std::filesystem::path gravity_file;  // optional: gravity.txt in the model's image names
  // optional: the model's world up axis, e.g. "+z", or "auto" (estimate_up_from_cameras)
  std::string up;
  bool overwrite = false;
  void check() const;  // throws lmb::Error naming the option
};

// The up direction of a model's world estimated from its cameras: minus the mean of the cameras'
// image "down" directions (each camera's +y axis in the world frame), the assumption of COLMAP's
// `model_orientation_aligner --method IMAGE-ORIENTATION`: cameras held upright on average (no
// systematic roll). Pitch cancels only when cameras look up as much as down; a camera that
// looks down at a table tilts the estimate towards its viewing direction.
struct UpEstimate {
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();  // unit, world frame
  int cameras = 0;
  // Length of the mean of the unit down directions: 1 when all cameras' down axes are parallel,
  // near 0 when they cancel (then the estimate means little).
  double mean_resultant_length = 0.0;
  std::string nearest_axis;       // the world axis closest to `up`: "+x", "-x", ..., "-z"
  double nearest_axis_deg = 0.0;  // the angle between `up` and that axis
};

// Throws lmb::Error for no cameras or down directions that cancel (mean length below 1e-6).
UpEstimate estimate_up_from_cameras(const std::vector<Rigid3d>& cam_from_world);

// How deep the model's 3D points lie in the images that observe them (points3D with tracks), in
// model units: what `lboost map --max-depth` (default 40, in the same units) must cover. A
// reconstruction without a scale reference has arbitrary units.
struct DepthStats {
  int64_t observations = 0;  // track elements in front of their camera
  double median = 0.0;
  double p95 = 0.0;  // 95th percentile
};

// Depth statistics over every track element of every point; nullopt when the model has no
// points with tracks (e.g. a text model without points3D.txt).
std::optional<DepthStats> observed_point_depths(const ColmapModel& model);

struct ColmapImportStats {
  int images = 0;
  int map_frames = 0;
  int query_frames = 0;
  bool binary = false;  // the model was read from .bin files
  bool has_gravity = false;
  std::optional<UpEstimate> up_estimate;  // with --up auto
  std::optional<DepthStats> depths;       // when the model has points with tracks
  // Names of the --gravity-file's lines that are no image of the model (e.g. photos the
  // reconstruction did not register), sorted; they are skipped.
  std::vector<std::string> gravity_lines_unused;
};

// Throws lmb::Error (one line naming file, record and reason) for malformed models, missing or
// unreadable images, a gravity file without a line for an image of the model, or an unusable split.
ColmapImportStats import_colmap(const ColmapImportOptions& options);

}  // namespace lmb
