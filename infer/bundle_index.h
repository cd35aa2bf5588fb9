// The index of a bundle of area models, bundle.txt (docs/areas.md): which model file holds each
// area, how to check that file, and where the area lies. Read and written here; AreaBundle
// (infer/area_bundle.h) loads the areas it names.
//
//   lmb-bundle 4
//   reach 5.0558576932189325        metres: how far cameras see (the areas file's reach)
//   map 0123456789abcdef            fingerprint_map of the map the areas split (common/feature_space.h)
//   calibration W0 .. W6 BIAS THRESHOLD SAMPLES POSITIVE PRECISION   (optional: the bundle's pose
//                                   calibration, PoseCalibration's fields, fitted by `lboost bundle --map`)
//   walk_calibration W0 .. W3 BIAS THRESHOLD TRANSLATION_SCALE_M ROTATION_SCALE_DEG MAX_GAP ADDS NOISE_M
//                    NOISE_DEG STEP_M STEP_DEG SAMPLES POSITIVE PRECISION   (optional, version 4, after
//                                   `calibration`: the walk calibration of track(), WalkCalibration's fields)
//   areas 21
//   area 0 file area-0.lbm bytes 6246098 crc32 1a2b3c4d landmarks 6866 first_landmark 0 last_landmark 9120
//          classes 0123456789abcdef cell LO_X LO_Y LO_Z HI_X HI_Y HI_Z            (one line)
//   ...
// `file` is a file name in the index's folder (no folder separator, not "." or ".."; two areas never
// share one). `landmarks`, `first_landmark`, `last_landmark` and `classes` describe the area's model:
// its class count, smallest and largest map landmark id, and fingerprint_classes() of its classes'
// landmark ids and positions, so a model of another area, split or map is refused when it loads even
// when its size and CRC-32 were copied into the index. Cell ends may be -inf / inf. Lines starting
// with '#' are comments.
//
// Versions 1 to 3 are still read (no `walk_calibration`). Versions 1 and 2 (no `map` line, areas
// without the landmark range and classes; 2 has a calibration): their map is unknown
// (map_fingerprint 0) and their areas are checked by class count only.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/types.h"
#include "infer/export.h"
#include "infer/pose_confidence.h"
#include "infer/walk_confidence.h"

namespace lmb {

class Model;

struct LMB_INFER_EXPORT BundleArea {
  int32_t id = 0;
  std::string file;                                   // the model file's name in the bundle folder
  uint64_t bytes = 0;                                 // its size
  uint32_t crc32 = 0;                                 // CRC-32 of the whole file
  int64_t landmarks = 0;                              // its classes
  landmark_t first_landmark = 0;                      // the smallest map landmark id of its classes
  landmark_t last_landmark = 0;                       // the largest
  uint64_t classes = 0;                               // fingerprint_classes() of its model (0: not recorded)
  Eigen::Vector3d cell_lo = Eigen::Vector3d::Zero();  // the area's cell (world frame, metres);
  Eigen::Vector3d cell_hi = Eigen::Vector3d::Zero();  // ends may be -inf / +inf
  // Euclidean distance from p to the cell (0 inside).
  double distance(const Eigen::Vector3d& p) const;
};

struct LMB_INFER_EXPORT BundleIndex {
  static constexpr int kVersion = 4;  // the version write_bundle_index writes
  int version = kVersion;             // as read
  double reach = 0.0;
  // fingerprint_map of the map the areas split; 0 = unknown (versions 1 and 2).
  uint64_t map_fingerprint = 0;
  std::optional<PoseCalibration> calibration;
  // The walk calibration of BundleLocalizer::track (version 4; only beside `calibration`).
  std::optional<WalkCalibration> walk_calibration;
  std::vector<BundleArea> areas;
};

// 64-bit fingerprint (not cryptographic: it catches another model, not an attack) of a model's
// classes: their count, map landmark ids and positions, bit for bit.
LMB_INFER_EXPORT uint64_t fingerprint_classes(const Model& model);

// The entry of area `id` for a model whose file `file` has the bytes `image`: size, CRC-32, class
// count, landmark range and classes fingerprint (the cell is left to the caller).
LMB_INFER_EXPORT BundleArea describe_area(int32_t id, const std::string& file, const std::string& image,
                                          const Model& model);

// Throws lmb::Error "<what>: ..." unless `model` is the one `area` describes (class count, and for
// entries that record them, landmark range and classes fingerprint).
LMB_INFER_EXPORT void check_area_model(const BundleArea& area, const Model& model, const std::string& what);

// Throws lmb::Error "<where>: ..." for an index no bundle can have: a reach that is not finite
// and >= 0, no area, an area whose id is not its position, a file name that is not a plain name in
// the folder or is used twice, a calibration out of range.
LMB_INFER_EXPORT void check_bundle_index(const BundleIndex& index, const std::string& where);

// Writes the index atomically at `path` (version 3). Throws lmb::Error naming the path: an entry
// whose id is not its position, a file name that is not a plain name in the folder or is used
// twice, a zero map fingerprint, a reach or calibration out of range.
LMB_INFER_EXPORT void write_bundle_index(const std::filesystem::path& path, const BundleIndex& index);

// Reads and checks an index (versions 1 to 3). Throws lmb::Error "<path> line <n>: <what>" (or
// naming the file when it cannot be read).
LMB_INFER_EXPORT BundleIndex read_bundle_index(const std::filesystem::path& path);

}  // namespace lmb
