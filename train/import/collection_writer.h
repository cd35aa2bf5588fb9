// Writes a collection (the folder `lboost map` reads) from posed images that live elsewhere:
//   OUT/sparse/{cameras,images,points3D}.txt   COLMAP text model (no 2D points, no 3D points)
//   OUT/images/<name>                          absolute symbolic links to the original files
//   OUT/gravity.txt                            per-image gravity in the camera frame (optional)
//   OUT/sessions.txt                           the sessions (optional; common/io/session_file.h)
// The image data is never copied.
#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/io/colmap_model.h"
#include "common/landmark_map.h"

namespace lmb {

struct CollectionImage {
  ColmapImage image;                              // name: the collection name, e.g. "map/0001.jpg"
  std::filesystem::path source;                   // the original file; linked by absolute path
  std::optional<Eigen::Vector3d> gravity_in_cam;  // unit, down; required for all or none
};

// Writes the collection, with sessions.txt when `sessions` is not empty (every image name must
// then start with a session's folder). An existing non-empty OUT is refused unless `overwrite`,
// which removes only OUT/sparse, OUT/images, OUT/gravity.txt and OUT/sessions.txt. Throws
// lmb::Error when a source file is missing, a name is used twice, gravity is given for some images
// only, an image is in no session, or a write fails; a failed write leaves nothing this call
// created (OUT itself included when it did not exist).
void write_collection(const std::filesystem::path& out_dir, const std::map<int, Camera>& cameras,
                      const std::vector<CollectionImage>& images, bool overwrite,
                      const std::vector<MapSession>& sessions = {});

}  // namespace lmb
