// The camera and the two recording sessions of a rendered world: a map session (two walks along the
// corridor, one each way, yaw swinging towards the walls) and a query session (a different lateral
// offset, height, yaw pattern and lighting over the same places).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/rigid3.h"
#include "train/world/renderer.h"
#include "train/world/world_model.h"

namespace lmb {

// The rendered camera: COLMAP OPENCV, 640 x 480, fx = fy = 460, k1 = -0.22, k2 = 0.05, small p1/p2;
// `scale` resizes the image and the focal length and principal point along (same field of view
// and distortion).
Camera world_camera(double scale = 1.0);

// cam_from_world of a camera at `centre` (world, metres) looking along heading `yaw` (radians,
// 0 = +x, counter-clockwise about +z), tilted up by `pitch` and rolled by `roll` (radians, about the
// optical axis). Camera frame: x right, y down, z forward; with zero pitch and roll the camera's
// down axis is world -z (gravity).
Rigid3d cam_from_world_pose(const Eigen::Vector3d& centre, double yaw, double pitch, double roll);

struct Session {
  std::string name;                      // "map" or "query": the image folder
  std::vector<Rigid3d> cam_from_world;   // one per frame
  Lighting lighting;
  // Trajectory parameters for world.json.
  double lateral_m = 0, height_m = 0, yaw_amplitude_deg = 0, yaw_period_m = 0;
};

// `frames` frames each; deterministic in the world's seed. Throws lmb::Error when frames < 1.
Session make_map_session(const World& world, int frames);
Session make_query_session(const World& world, int frames);

}  // namespace lmb
