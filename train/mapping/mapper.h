// The mapper: one or more collections (COLMAP sparse model + images) -> lmb::LandmarkMap. Map and
// query frames are mapped jointly so that query keypoints get their true landmark; landmarks need
// >= 3 map-frame observations, so query-only tracks never become landmarks. Every frame belongs to
// a session (common/landmark_map.h; a collection names them in sessions.txt,
// common/io/session_file.h): tracks join frames of every map and query session (their poses share
// one world frame); outside sessions are never matched.
//
//   detect (BRISK/ORB) -> frame pairs by pose -> guided matching -> conflict-free tracks ->
//   OpenGV triangulation + refinement -> landmarks with a quality score -> LandmarkMap
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/landmark_map.h"
#include "train/mapping/frame_pairs.h"
#include "train/mapping/guided_matching.h"
#include "train/mapping/keypoint_detection.h"
#include "train/mapping/triangulation.h"

namespace lmb {

struct MapperOptions {
  DetectorOptions detector;
  PairOptions pairs;
  MatchingOptions matching;
  TriangulationOptions triangulation;
  int min_map_observations = 3;  // landmarks need this many inlier map-frame observations
  // For a collection without sessions.txt: image names starting with it are the query session
  // "query", the others the map session "map" ("" = all map).
  std::string query_prefix = "query/";
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();  // world up axis (unit); gravity is -up
  // Optional per-image gravity (common/io/gravity_file.h: IMAGE_NAME gx gy gz, down, camera
  // frame); when set it replaces `up` for every frame. Used by map_collection (one collection);
  // map_collections takes one per collection instead.
  std::filesystem::path gravity_file;
  int threads = 2;
  void check() const;  // throws lmb::Error naming the field
};

// One frame's input to the mapping core: pose, camera and detected features.
struct MapperFrame {
  std::string name;
  camera_t camera = 0;  // index into the cameras passed along
  int32_t session = 0;  // index into the sessions passed along
  Rigid3d cam_from_world;
  bool is_query = false;                          // must equal (its session's kind != map)
  std::optional<Eigen::Vector3d> gravity_in_cam;  // unit, down; unset: from MapperOptions::up
  std::vector<Keypoint> keypoints;
  std::vector<uint8_t> descriptors;  // keypoints.size() * descriptor_bytes
};

struct MapperStats {
  int num_sessions = 0;
  int num_map_frames = 0;
  int num_query_frames = 0;  // frames of query and outside sessions
  int num_outside_frames = 0;
  int64_t num_keypoints = 0;
  int64_t num_pairs = 0;
  int64_t num_matches = 0;
  int64_t num_tracks = 0;  // tracks of >= 2 keypoints before triangulation
  int64_t num_landmarks = 0;
  int64_t num_map_observations = 0;    // map keypoints with a landmark
  int64_t num_query_observations = 0;  // query keypoints with a landmark
  double mean_map_observations = 0;    // per landmark
  double mean_reprojection_error_px = 0;
  double detect_seconds = 0, match_seconds = 0, triangulate_seconds = 0, total_seconds = 0;
};

// Parses "+z", "-z", "+y", "-y", "+x", "-x" (a missing sign means +); throws lmb::Error otherwise.
Eigen::Vector3d parse_up_axis(const std::string& text);

// Landmark quality used for top-K selection (higher is better):
//   log(1 + map observations) * exp(-mean reprojection error / 2 px) * (1 - exp(-angle / 10 deg))
// where angle is the largest triangulation angle between two observations.
float landmark_quality(int num_map_observations, double mean_reprojection_error_px, double triangulation_angle_deg);

// The mapping core on already detected features (everything after detection). frames keep their
// order in the map; within a session they are in capture order. Throws lmb::Error on inconsistent
// input (camera or session index, a frame's is_query against its session's kind, descriptor sizes,
// invalid session names).
LandmarkMap build_landmark_map(const std::vector<Camera>& cameras, const std::vector<MapSession>& sessions,
                               const std::vector<MapperFrame>& frames, const std::string& detector,
                               int descriptor_bytes, const MapperOptions& options, MapperStats* stats = nullptr);
// The same with the sessions "map" and "query" made from the frames' is_query flags (the frames'
// session fields are ignored).
LandmarkMap build_landmark_map(const std::vector<Camera>& cameras, const std::vector<MapperFrame>& frames,
                               const std::string& detector, int descriptor_bytes, const MapperOptions& options,
                               MapperStats* stats = nullptr);

// One collection to map, for map_collections.
struct CollectionInput {
  std::filesystem::path dir;  // holds sparse/ and images/ (and sessions.txt, optional)
  // With several collections, frame and session names in the map become "LABEL/NAME" (default:
  // the folder's name); ignored when mapping one collection.
  std::string label;
  std::filesystem::path gravity_file;  // optional, as MapperOptions::gravity_file
};

// Reads each collection's sparse/{cameras,images,points3D}.txt (or .bin), its sessions (sessions.txt,
// else options.query_prefix) and its images under images/, detects keypoints and runs
// build_landmark_map on all of them together: frames in collection order, then image-id order;
// cameras and sessions in collection order. The collections' poses must share one world frame.
// Throws lmb::Error naming the file and reason (missing or unreadable image, image size not the
// camera's, bad model, sessions or gravity files, two collections with one label).
LandmarkMap map_collections(const std::vector<CollectionInput>& collections, const MapperOptions& options,
                            MapperStats* stats = nullptr);

// One collection, with options.gravity_file; frame and session names as in the collection.
LandmarkMap map_collection(const std::filesystem::path& collection_dir, const MapperOptions& options,
                           MapperStats* stats = nullptr);

}  // namespace lmb
