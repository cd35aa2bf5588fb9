// `lboost scene`: a map and localized poses where users look at 3D reconstructions. A COLMAP text
// model (cameras.txt, images.txt, points3D.txt: COLMAP's GUI, `colmap model_converter`, Open3D)
// and an ASCII PLY point cloud (MeshLab, CloudCompare, Blender) of the landmarks and the cameras.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/io/colmap_model.h"
#include "common/landmark_map.h"
#include "common/rigid3.h"

namespace lmb::cli {

// A localized photo (or query frame) to show with the map.
struct ScenePhoto {
  std::string name;  // its image name in the model ("localized/<file name>")
  Camera camera;
  Rigid3d cam_from_world;
};

// The colours of the PLY's camera centres.
inline const Eigen::Matrix<uint8_t, 3, 1> kMapFrameColor(40, 110, 255);         // blue
inline const Eigen::Matrix<uint8_t, 3, 1> kLocalizedColor(255, 40, 40);         // red
inline const Eigen::Matrix<uint8_t, 3, 1> kUnseenLandmarkColor(128, 128, 128);  // grey

struct SceneStats {
  int64_t coloured_landmarks = 0;  // landmarks with a colour sampled from a map frame's image
  int64_t images_read = 0;         // map frames whose image was read
  int64_t images_missing = 0;      // map frames whose image could not be read (or no image folder)
};

// The map as a COLMAP model: every camera of the map (CAMERA_ID = index + 1), then one camera per
// distinct camera of `photos` that is not one of the map's (same model, size and parameters); every frame of a map
// session as an image (IMAGE_ID = 1, 2, ... in frame order, NAME = the frame's name, its keypoints as POINTS2D, each
// linked to its landmark's POINT3D_ID or -1); each photo as an image after them (no 2D points); every landmark as a 3D
// point (POINT3D_ID = landmark id + 1, ERROR = its mean reprojection error, TRACK = its map-frame
// observations). A landmark's colour is the mean over its map-frame observations of the pixel
// under the keypoint in the frame's image read from `images_dir` (the collection's image folder,
// in colour); grey (kUnseenLandmarkColor) without an image folder or a readable image. Throws
// lmb::Error for a photo name that is not a valid image name.
ColmapModel map_scene_model(const LandmarkMap& map, const std::vector<ScenePhoto>& photos,
                            const std::filesystem::path& images_dir, SceneStats* stats);

// The localized entries of a poses file of `lboost localize`: "photos" (photo mode: their
// "camera" is the file's) or "frames" (--map mode: each frame's camera from `map`), those with
// success true, named "localized/<file name>" ("localized/<frame name>" for frames; a repeated
// name gets "-2", "-3", ... before its extension). Throws lmb::Error naming the file: not JSON,
// neither "photos" nor "frames", a localized entry without cam_from_world, a frame the map lacks.
std::vector<ScenePhoto> read_localized_poses(const std::filesystem::path& poses_json, const LandmarkMap& map);

// An ASCII PLY point cloud: one coloured vertex per 3D point of
// `model`, then one per image centre: the first `num_map_images` images in kMapFrameColor, the
// rest in kLocalizedColor. Written atomically.
void write_scene_ply(const ColmapModel& model, size_t num_map_images, const std::filesystem::path& path);

}  // namespace lmb::cli
