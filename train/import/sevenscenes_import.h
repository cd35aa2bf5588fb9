// `lboost import 7scenes`: RGB(-D) video with per-frame poses in the layout of the relocalization
// data sets Microsoft 7-Scenes and Stanford 12-Scenes -> a collection (see
// train/import/collection_writer.h). A frame is
//   frame-NNNNNN.color.{png,jpg}   the colour image
//   frame-NNNNNN.pose.txt          a 4x4 camera-to-world matrix (world_from_cam), metres: 4 rows
//                                  of 4 numbers, the last row 0 0 0 1
// Three layouts of the data folder DIR:
//   DIR/rgb/frame-*.color.*  with  DIR/pose/frame-*.pose.txt       (one recording)
//   DIR/frame-*.color.*      with the pose files beside the images  (one recording, 12-Scenes data/)
//   DIR/seq-01/, DIR/seq-02/, ... each holding frames in one of the two layouts above (7-Scenes)
// Optional files of DIR: camera-intrinsics.txt (a 3x3 K: fx 0 cx / 0 fy cy / 0 0 1) and
// gravity-direction.txt (one world-frame vector pointing down: the direction of gravity).
// A pose with a non-finite entry (7-Scenes and 12-Scenes mark lost tracking with inf) skips its
// frame; a pose file that is not a 4x4 rigid transform is an error.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/landmark_map.h"
#include "common/rigid3.h"

namespace lmb {

// One item of --map-frames / --query-frames: frames FIRST-LAST (inclusive) or one frame N of the
// recording, or a sequence folder NAME (all its frames), or NAME:FIRST-LAST.
struct FrameItem {
  std::string text;      // as given, for messages
  std::string sequence;  // empty: the recording of a single-recording folder
  bool all_frames = false;
  int64_t first = 0, last = 0;
};

// Parses "0-499", "0-99,200-299", "7", "seq-01,seq-02", "seq-01:0-499". Throws lmb::Error naming
// `option` and the item: an empty item, a range whose end precedes its start, a number of more
// than 9 digits.
std::vector<FrameItem> parse_frame_items(const std::string& text, const std::string& option);

// Reads a pose file: world_from_cam with the rotation projected onto the nearest rotation matrix.
// Returns nullopt when an entry is not finite (a skipped frame). Throws lmb::Error naming the file
// (and line) for a file that is not 4 rows of 4 numbers, a last row other than 0 0 0 1, or a
// rotation block that is not a rotation (R^T R - I beyond kPoseOrthonormalTolerance, or a
// reflection).
std::optional<Rigid3d> read_sevenscenes_pose(const std::filesystem::path& path);
inline constexpr double kPoseOrthonormalTolerance = 1e-2;  // largest entry of |R^T R - I|

// Reads a 3x3 camera matrix K (fx 0 cx / 0 fy cy / 0 0 1). Throws lmb::Error naming the file for
// another shape, a non-finite or non-number entry, a skew, a last row other than 0 0 1, or a
// focal length that is not positive.
Eigen::Matrix3d read_intrinsics_matrix(const std::filesystem::path& path);

// Reads one 3-vector (on one line or three). Throws lmb::Error naming the file for another count,
// non-finite entries or the zero vector. Returns it normalized.
Eigen::Vector3d read_world_vector(const std::filesystem::path& path);

struct SevenScenesImportOptions {
  std::filesystem::path data_dir;  // DIR
  std::filesystem::path out_dir;
  std::string map_frames;    // required, parse_frame_items
  std::string query_frames;  // optional
  int stride = 1;            // every stride-th frame of each item (FIRST, FIRST + stride, ...)
  // The camera: --intrinsics FILE, else --focal (fx = fy) with --cx / --cy (default: the image
  // centre), else DIR/camera-intrinsics.txt.
  std::filesystem::path intrinsics_file;
  std::optional<double> focal, cx, cy;
  // Gravity (gravity.txt): "" = DIR/gravity-direction.txt when present, else none; "none"; or a
  // file holding the world-frame down vector. gravity_up: the world's up vector instead.
  std::string gravity;
  std::optional<Eigen::Vector3d> gravity_up;
  bool overwrite = false;
  void check() const;  // throws lmb::Error naming the option
};

struct SevenScenesImportStats {
  std::string layout;  // "rgb/ and pose/ folders", "frames in the folder", "sequence folders"
  int selected_frames = 0;
  int imported_frames = 0;
  int map_frames = 0;
  int query_frames = 0;
  int skipped_invalid_pose = 0;            // a non-finite pose entry
  std::vector<std::string> skipped_poses;  // their pose files, in order
  Camera camera;
  std::string camera_source;  // e.g. "DIR/camera-intrinsics.txt", "--focal, --cx, --cy"
  std::optional<Eigen::Vector3d> gravity_down_world;
  std::string gravity_source;  // e.g. "DIR/gravity-direction.txt", "--gravity-up"
  // With gravity: the angle between each imported camera's image down axis (camera +y) and the
  // gravity vector: small for upright cameras when the vector points down.
  double image_down_median_deg = 0, image_down_p10_deg = 0, image_down_p90_deg = 0;
  std::vector<MapSession> sessions;  // as written to sessions.txt
  std::vector<int> session_frames;   // frames of each session
};

// Imports the frames. Throws lmb::Error (one line naming the file or option and the reason) for
// an unknown layout, a selected frame without an image or pose file, a frame selected twice, a
// malformed pose, intrinsics or gravity file, missing intrinsics, no map frame left, or a failed
// write (write_collection).
SevenScenesImportStats import_sevenscenes(const SevenScenesImportOptions& options);

}  // namespace lmb
