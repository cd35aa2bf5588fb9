// The camera and the recording sessions of a rendered world. A map session walks the corridor
// twice, once each way, yaw swinging towards the walls; every map session has its own lanes, camera
// height, yaw and pitch pattern and lighting (time of day). Query sessions walk the same places
// with lanes, heights and lighting unlike every map session's. Session 0 of each kind is the
// world's original map or query session.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/landmark_map.h"
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

// One straight pass of a session along the corridor.
struct PassParams {
  double heading = 0;            // 0 (+x) or pi (-x)
  double lateral_m = 0;          // y of the walk
  double height_m = 1.5;         // camera height
  double yaw_amplitude_deg = 0;  // yaw swing towards the walls
  double yaw_period_m = 3;
  double pitch_mean_deg = 0, pitch_amplitude_deg = 0, pitch_period_m = 2;
  double roll_amplitude_deg = 0;
  double sample_phase = 0;  // fraction of a frame step by which the samples are shifted
};

struct Session {
  std::string name;  // the image folder: "map", "map-2", ..., "query", "query-2", ...
  SessionKind kind = SessionKind::kMap;
  std::string time_of_day;              // a label of the lighting, for world.json
  std::vector<Rigid3d> cam_from_world;  // one per frame
  Lighting lighting;
  uint64_t frame_key_base = 0;  // frame i is rendered with noise key frame_key_base | i
  // cam_from_world are poses in the corridor the session is rendered in; the collection records
  // them moved by this offset of the world frame (the outside session: (0, kOutsideOffsetY, 0)).
  Eigen::Vector3d world_offset = Eigen::Vector3d::Zero();
  // Frame i's pose as recorded: cam_from_world[i] of a world moved by world_offset.
  Rigid3d recorded_cam_from_world(size_t i) const;
  PassParams passes[2];  // forward, backward (world.json)
};

// `frames` frames each (the first ceil(frames / 2) walk forward); deterministic in the world's
// seed and the index. Index 0 is the world's original session of the kind; map sessions 1..3 and
// query sessions 1..2 vary lanes, height, yaw and pitch pattern and lighting. Throws lmb::Error
// when frames < 1 or the index is outside 0..kMaxMapSessions - 1 (0..kMaxQuerySessions - 1).
Session make_map_session(const World& world, int frames, int index = 0);
Session make_query_session(const World& world, int frames, int index = 0);

// The outside session: `frames` frames in `outside_world` (build_world with region 1), the first
// query session's style, named "outside", kind kOutside, world_offset (0, kOutsideOffsetY, 0).
Session make_outside_session(const World& outside_world, int frames);

// The sessions of world.options: map_sessions map sessions sharing map_frames (the first
// map_frames % map_sessions get one frame more), then query_sessions query sessions of
// query_frames frames each.
std::vector<Session> make_world_sessions(const World& world);

}  // namespace lmb
