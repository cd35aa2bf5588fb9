// `lboost import tum`: a TUM RGB-D sequence (rgb.txt, groundtruth.txt, accelerometer.txt, rgb/)
// -> a collection (see train/import/collection_writer.h). TUM's formats
// (https://cvg.cit.tum.de/data/datasets/rgbd-dataset/file_formats):
//   rgb.txt            timestamp filename
//   groundtruth.txt    timestamp tx ty tz qx qy qz qw: world_from_cam (the colour camera's optical
//                      centre in the motion-capture world), seconds, metres
//   accelerometer.txt  timestamp ax ay az, m/s^2, the Kinect's accelerometer
// Lines starting with '#' are comments.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/landmark_map.h"
#include "common/rigid3.h"

namespace lmb {

struct TumImage {
  double time_s = 0.0;
  std::string timestamp;  // as written in rgb.txt, used for the collection's image names
  std::string file;       // relative to the sequence folder, e.g. "rgb/1305031229.528748.jpg"
};

struct TumTrajectory {
  std::vector<double> time_s;           // strictly increasing
  std::vector<Rigid3d> world_from_cam;  // one per time
};

struct TumAccelerometer {
  std::vector<double> time_s;               // non-decreasing
  std::vector<Eigen::Vector3d> accel_mps2;  // one per time, in the accelerometer's frame
};

// Readers; each throws lmb::Error naming the file, line and reason (field count, non-numbers,
// non-finite values, non-unit quaternions, timestamps out of order).
std::vector<TumImage> read_tum_image_list(const std::filesystem::path& path);
TumTrajectory read_tum_trajectory(const std::filesystem::path& path);
TumAccelerometer read_tum_accelerometer(const std::filesystem::path& path);

// world_from_cam at time t: linear interpolation of the position and slerp of the rotation between
// the last sample at or before t and the first sample after it. Empty when either is missing or
// further than max_gap_s from t (an exact sample hit needs only itself).
std::optional<Rigid3d> interpolate_pose(const TumTrajectory& trajectory, double t, double max_gap_s);

// Mean accelerometer reading over [t - half_window_s, t + half_window_s]; when that window is
// empty, the nearest reading if it is within max_gap_s; else empty.
std::optional<Eigen::Vector3d> accelerometer_at(const TumAccelerometer& accel, double t, double half_window_s,
                                                double max_gap_s);

// The rotation from the Kinect accelerometer's frame to the colour camera's frame (x right, y
// down, z forward), measured on freiburg1_rpy against the motion-capture poses (world z up): a
// half turn about the optical axis, i.e. (ax, ay, az) -> (-ax, -ay, az). The accelerometer reads
// the reaction to gravity (up, +9.8 m/s^2 when still), so gravity (down) in the camera frame is
// -(kTumCamFromAccel * a).
Eigen::Matrix3d tum_cam_from_accel();

// The TUM freiburg1 colour camera, COLMAP's FULL_OPENCV.
inline constexpr const char* kTumFreiburg1Camera =
    "FULL_OPENCV 640 480 517.3 516.5 318.6 255.3 0.2624 -0.9531 -0.0054 0.0026 1.1633 0 0 0";

// Parses "MODEL WIDTH HEIGHT PARAMS..." (COLMAP's cameras.txt line without the id).
Camera parse_camera_line(const std::string& text);
// Parses "+x", "-x", "+y", "-y", "+z", "-z".
Eigen::Vector3d parse_axis(const std::string& text, const char* flag);

// Sequences are imported into sessions of one collection (sessions.txt, common/io/session_file.h):
//   - a map sequence (data_dirs) is split by `split` into its map frames, the map session NAME,
//     and the rest, the query session NAME-query (same place, same recording: held-out frames);
//   - a query sequence (query_dirs) is one query session NAME, all its frames queries.
// NAME is session_names[i] (map sequences first, then query sequences) or, by default, the
// sequence folder's name; a single map sequence without query sequences keeps the names "map" and
// "query". Images are named NAME/<timestamp><extension>, sequence after sequence in time order. The
// sequences' ground truth must share one motion-capture world (e.g. the freiburg1 sequences) and
// one camera.
struct TumImportOptions {
  std::vector<std::filesystem::path> data_dirs;   // map sequences (rgb.txt, groundtruth.txt, ...), >= 1
  std::vector<std::filesystem::path> query_dirs;  // query sequences
  std::vector<std::string> session_names;         // empty, or one per sequence
  std::filesystem::path out_dir;                  // the collection to write
  std::string split = "every:3";                  // see train/import/split_rule.h; applied to each map sequence
  // Gravity written to gravity.txt: "accelerometer" (per image, from accelerometer.txt),
  // "groundtruth-up" (R_cam_from_world * -world_up from the interpolated ground truth), "none".
  std::string gravity = "accelerometer";
  std::string world_up = "+z";  // the motion-capture world's up axis (TUM: +z)
  std::string camera = kTumFreiburg1Camera;
  // Seconds added to each image timestamp before looking up its ground-truth pose: positive when
  // the ground truth lags the images.
  double time_offset_s = 0.0;
  double max_gap_s = 0.020;            // frames without ground truth this close are skipped
  double accel_half_window_s = 0.010;  // accelerometer readings averaged per image
  Eigen::Matrix3d cam_from_accel = tum_cam_from_accel();
  bool overwrite = false;
  void check() const;  // throws lmb::Error naming the option
};

// How well the accelerometer's gravity agrees with the ground truth's (R_cam_from_world * -up),
// over the imported frames with both.
struct GravityAgreement {
  int frames = 0;
  double median_deg = 0, mean_deg = 0, p90_deg = 0;
  // Median angle for each candidate world up axis (+x, -x, +y, -y, +z, -z) with the given
  // accelerometer frame: the smallest names the world's vertical.
  double median_deg_by_world_axis[6] = {0, 0, 0, 0, 0, 0};
  // The time offset (added to image timestamps for the ground truth, scanned over +-60 ms in 5 ms
  // steps) with the smallest median angle, and that angle.
  double best_time_offset_s = 0, best_time_offset_median_deg = 0;
  // The least-squares rotation cam_from_accel fitted to all frames, its angle to the assumed one,
  // and the median angle after applying it.
  Eigen::Matrix3d fitted_cam_from_accel = Eigen::Matrix3d::Identity();
  double fitted_rotation_offset_deg = 0, fitted_median_deg = 0;
};

struct TumImportStats {
  int listed_frames = 0;  // lines of the sequences' rgb.txt
  int imported_frames = 0;
  int map_frames = 0;
  int query_frames = 0;
  int skipped_no_pose = 0;                            // no ground truth within max_gap_s
  int skipped_no_accelerometer = 0;                   // gravity = accelerometer and no reading within max_gap_s
  std::optional<GravityAgreement> gravity_agreement;  // when accelerometer.txt exists
  std::vector<MapSession> sessions;                   // as written to sessions.txt (sessions with frames only)
  std::vector<int> session_frames;                    // frames of each session
};

// Imports the sequences. Throws lmb::Error for unreadable inputs or output (see the readers and
// write_collection), session names that are invalid or used twice, a split leaving a map sequence
// without map frames, or a list entry naming no frame of any map sequence.
TumImportStats import_tum(const TumImportOptions& options);

}  // namespace lmb
