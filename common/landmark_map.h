// The landmark map: what `lboost map` produces and everything downstream reads. Plain data; the
// HDF5 file format lives in common/io/map_h5.h.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/rigid3.h"
#include "common/types.h"

namespace lmb {

// What a session (one recording: a walk, a sequence) is for.
//   kMap      its frames build the landmarks and train the classifier
//   kQuery    held out of training; localized and evaluated (its keypoints carry their true
//             landmark from joint mapping)
//   kOutside  held out, recorded somewhere the map does not cover: no keypoint has a landmark, and
//             the right answer for its frames is no pose
enum class SessionKind : uint8_t { kMap = 0, kQuery = 1, kOutside = 2 };

// "map", "query", "outside".
const char* session_kind_name(SessionKind kind);
// Parses a name of session_kind_name; throws lmb::Error "<where>: ..." for anything else.
SessionKind parse_session_kind(const std::string& text, const std::string& where);

struct MapSession {
  std::string name;  // unique in its map, e.g. "map", "map-2", "query" (no white space)
  SessionKind kind = SessionKind::kMap;
};

struct MapFrame {
  std::string name;     // image name in the collection ("map/000012.png")
  camera_t camera = 0;  // index into LandmarkMap::cameras
  int32_t session = 0;  // index into LandmarkMap::sessions
  Rigid3d cam_from_world;
  Eigen::Vector3d gravity_in_cam = Eigen::Vector3d(0, 1, 0);  // unit, pointing down, camera frame
  // True for every frame whose session is not a map session (query and outside frames): these
  // frames and their keypoints never reach training. Always equals sessions[session].kind != kMap.
  bool is_query = false;
  int64_t first_keypoint = 0;  // this frame's keypoints are [first, first + num)
  int32_t num_keypoints = 0;
};

struct Landmark {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // world frame
  float quality = 0.f;                                 // higher is better; used for top-K selection
  float mean_reprojection_error = 0.f;                 // pixels, over all observations
  int32_t num_map_observations = 0;
  int32_t num_query_observations = 0;
};

struct LandmarkMap {
  std::string detector = "BRISK";
  int descriptor_bytes = 0;
  std::vector<Camera> cameras;
  std::vector<MapSession> sessions;  // every frame names one; a map with frames has >= 1
  std::vector<MapFrame> frames;
  std::vector<Keypoint> keypoints;            // all frames' keypoints, frame after frame
  std::vector<uint8_t> descriptors;           // keypoints.size() * descriptor_bytes
  std::vector<landmark_t> keypoint_landmark;  // per keypoint: its landmark or kInvalidLandmarkId
  std::vector<Landmark> landmarks;

  const uint8_t* descriptor(int64_t keypoint) const { return descriptors.data() + keypoint * descriptor_bytes; }
  frame_t num_frames() const { return static_cast<frame_t>(frames.size()); }
  const MapSession& session_of(frame_t f) const { return sessions[static_cast<size_t>(frames[f].session)]; }
  // Index of the session called `name`, or -1.
  int32_t find_session(const std::string& name) const;
  // The frames of the map sessions (kind map, not flagged query), ascending.
  std::vector<frame_t> map_session_frames() const;
};

// The sessions of a map that has none yet (a format-1 map.h5, a map assembled by hand): "map"
// (kind map) for the frames with is_query unset and, when some frame has it set, "query" (kind
// query) for those; each frame's session is set to match. Throws lmb::Error when the map already
// has sessions.
void assign_sessions_from_query_flags(LandmarkMap* map);

}  // namespace lmb
