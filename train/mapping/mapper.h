// The mapper: one or more collections (COLMAP sparse model + images) -> lmb::LandmarkMap. Map and
// query frames are mapped jointly so that query keypoints get their true landmark; landmarks need
// >= 3 map-frame observations, so query-only tracks never become landmarks. Every frame belongs to
// a session (common/landmark_map.h; a collection names them in sessions.txt,
// common/io/session_file.h): tracks join frames of every map and query session (their poses share
// one world frame); outside sessions are never matched.
//
//   detect (BRISK/ORB) -> map frame pairs by pose -> guided matching -> tracks -> triangulation
//   (a first map) -> query frame pairs by pose and by view overlap of its points -> guided
//   matching -> conflict-free tracks -> OpenGV triangulation + refinement, outliers split off as
//   tracks of their own -> [camera intrinsics refined on the tracks, matching and triangulation
//   again] -> landmarks with a quality score -> LandmarkMap
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/landmark_map.h"
#include "train/mapping/camera_refinement.h"
#include "train/mapping/frame_pairs.h"
#include "train/mapping/guided_matching.h"
#include "train/mapping/keypoint_detection.h"
#include "train/mapping/triangulation.h"

namespace lmb {

// Whether the mapper refines the cameras' focal lengths on the map's own tracks (MapperOptions).
enum class FocalRefinement { kOff, kAuto, kOn };

// "off", "auto", "on"; parse throws lmb::Error on anything else.
std::string focal_refinement_name(FocalRefinement r);
FocalRefinement parse_focal_refinement(const std::string& text);

struct MapperOptions {
  DetectorOptions detector;
  // Frame pairs (frame_pairs.h): with pairs.max_center_distance > 0 the pose rule alone chooses
  // them; with 0 (default) the pose rule pairs the frames, and the overlap rule (overlap; its depth
  // range is matching's) adds the query frames' partners by view overlap with a first map made
  // from the map frames' pairs.
  PairOptions pairs;
  OverlapPairOptions overlap;
  MatchingOptions matching;
  TriangulationOptions triangulation;
  // Camera intrinsics refined on the map's tracks (poses fixed), then matching and triangulation
  // again with the refined cameras, up to refine_rounds times (fewer when the focal length moves
  // by less than 0.1%). The map stores the refined cameras. kAuto: first the focal check (one
  // refinement step, reported in MapperStats::focal_check), then the refinement when it moves a
  // camera's focal length by more than auto_refine_min_change (relative); kOff: the check alone,
  // reported and not applied; kOn: the refinement without the check.
  FocalRefinement refine_focal = FocalRefinement::kAuto;
  double auto_refine_min_change = 0.01;
  CameraRefinementOptions refinement;  // refinement.principal_point: also cx, cy
  int refine_rounds = 3;
  // While refining, an observation is a triangulation inlier up to this multiple of
  // triangulation.max_reprojection_error_px (the final triangulation uses the threshold itself).
  double refine_inlier_factor = 3.0;
  int min_map_observations = 3;  // landmarks need this many inlier map-frame observations
  // The outliers of a triangulated track (points joined by a wrong match) are triangulated again as
  // a track of their own, up to this many times per track.
  int track_splits = 12;
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

// The focal check of one camera: its focal length, the one a refinement step on the map's tracks
// moves it to, and the mean reprojection error of the observations it used, before and after.
struct FocalCheck {
  double focal_px = 0, fitted_focal_px = 0;
  double error_before_px = 0, error_after_px = 0;
  int64_t observations = 0;
};

struct MapperStats {
  int num_sessions = 0;
  int num_map_frames = 0;
  int num_query_frames = 0;  // frames of query and outside sessions
  int num_outside_frames = 0;
  int64_t num_keypoints = 0;
  int64_t num_pairs = 0;
  bool pairs_by_overlap = false;      // the overlap rule was used (no explicit pair distance)
  int64_t num_first_pass_pairs = 0;   // map-frame pairs by pose
  int64_t num_first_pass_points = 0;  // scene points of the first map, from those pairs
  int64_t num_query_pose_pairs = 0;   // query-map pairs by pose, kept beside the overlap pairs
  OverlapPairStats overlap;
  int64_t num_matches = 0;
  int64_t num_tracks = 0;  // tracks of >= 2 keypoints before triangulation
  int64_t num_landmarks = 0;
  int64_t num_map_observations = 0;    // map keypoints with a landmark
  int64_t num_query_observations = 0;  // query keypoints with a landmark
  double mean_map_observations = 0;    // per landmark
  double mean_reprojection_error_px = 0;
  // With the cameras refined (refined: refine_focal kOn, or kAuto after a focal check that moved
  // them): the cameras as given and as refined, the mean reprojection error of the
  // landmarks with each (the first and the final triangulation), the rounds run.
  std::vector<Camera> cameras_before, cameras_after;
  double reprojection_error_before_px = 0, reprojection_error_after_px = 0;
  int64_t landmarks_before = 0, query_observations_before = 0;
  int refine_rounds = 0;
  bool refined = false;
  std::vector<FocalCheck> focal_check;  // refine_focal kAuto or kOff: per camera
  // refine_seconds: the focal check and the camera refinement with its matching
  double detect_seconds = 0, match_seconds = 0, triangulate_seconds = 0, refine_seconds = 0, total_seconds = 0;
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
