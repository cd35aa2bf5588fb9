#include "train/import/tum_import.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include "common/error.h"
#include "common/io/colmap_model.h"
#include "common/io/session_file.h"
#include "common/stats.h"
#include "common/text_lines.h"
#include "common/text_parse.h"
#include "train/import/collection_writer.h"
#include "train/import/split_rule.h"

namespace lmb {

namespace fs = std::filesystem;

namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

// Calls fn("<path> line <n>", tokens) for each data line (common/text_lines.h).
template <typename Fn>
void for_each_data_line(const fs::path& path, Fn fn) {
  for (TextLineReader lines(path); lines.next();) fn(lines.where(), lines.tokens());
}

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * kRadToDeg;
}

const char* const kAxisNames[6] = {"+x", "-x", "+y", "-y", "+z", "-z"};

Eigen::Vector3d axis_vector(int k) {
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  v[k / 2] = k % 2 ? -1.0 : 1.0;
  return v;
}

}  // namespace

std::vector<TumImage> read_tum_image_list(const fs::path& path) {
  std::vector<TumImage> images;
  for_each_data_line(path, [&](const std::string& at, const std::vector<std::string>& tokens) {
    LMB_CHECK(tokens.size() == 2, at << ": expected 2 fields (timestamp filename), got " << tokens.size());
    TumImage im;
    im.timestamp = tokens[0];
    im.time_s = parse_finite_number(tokens[0], at, "timestamp");
    im.file = tokens[1];
    LMB_CHECK(images.empty() || im.time_s > images.back().time_s,
              at << ": timestamp " << tokens[0] << " is not after the previous one");
    images.push_back(im);
  });
  LMB_CHECK(!images.empty(), path.string() << ": no image listed");
  return images;
}

TumTrajectory read_tum_trajectory(const fs::path& path) {
  TumTrajectory trajectory;
  for_each_data_line(path, [&](const std::string& at, const std::vector<std::string>& tokens) {
    LMB_CHECK(tokens.size() == 8, at << ": expected 8 fields (timestamp tx ty tz qx qy qz qw), got " << tokens.size());
    const char* names[8] = {"timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"};
    double v[8];
    for (int k = 0; k < 8; ++k) v[k] = parse_finite_number(tokens[k], at, names[k]);
    LMB_CHECK(trajectory.time_s.empty() || v[0] > trajectory.time_s.back(),
              at << ": timestamp " << tokens[0] << " is not after the previous one");
    trajectory.time_s.push_back(v[0]);
    trajectory.world_from_cam.emplace_back(checked_rotation(v[7], v[4], v[5], v[6], at),
                                           Eigen::Vector3d(v[1], v[2], v[3]));
  });
  LMB_CHECK(!trajectory.time_s.empty(), path.string() << ": no pose");
  return trajectory;
}

TumAccelerometer read_tum_accelerometer(const fs::path& path) {
  TumAccelerometer accel;
  for_each_data_line(path, [&](const std::string& at, const std::vector<std::string>& tokens) {
    LMB_CHECK(tokens.size() == 4, at << ": expected 4 fields (timestamp ax ay az), got " << tokens.size());
    const double t = parse_finite_number(tokens[0], at, "timestamp");
    LMB_CHECK(accel.time_s.empty() || t >= accel.time_s.back(),
              at << ": timestamp " << tokens[0] << " is before the previous one");
    accel.time_s.push_back(t);
    accel.accel_mps2.emplace_back(parse_finite_number(tokens[1], at, "ax"), parse_finite_number(tokens[2], at, "ay"),
                                  parse_finite_number(tokens[3], at, "az"));
  });
  LMB_CHECK(!accel.time_s.empty(), path.string() << ": no reading");
  return accel;
}

std::optional<Rigid3d> interpolate_pose(const TumTrajectory& trajectory, double t, double max_gap_s) {
  const std::vector<double>& times = trajectory.time_s;
  const auto upper = std::upper_bound(times.begin(), times.end(), t);  // first sample after t
  if (upper == times.begin()) return std::nullopt;
  const size_t i0 = static_cast<size_t>(upper - times.begin()) - 1;
  const double t0 = times[i0];
  if (t - t0 > max_gap_s) return std::nullopt;
  if (t0 == t) return trajectory.world_from_cam[i0];
  if (upper == times.end()) return std::nullopt;
  const size_t i1 = i0 + 1;
  const double t1 = times[i1];
  if (t1 - t > max_gap_s) return std::nullopt;
  const double alpha = (t - t0) / (t1 - t0);
  const Rigid3d& a = trajectory.world_from_cam[i0];
  const Rigid3d& b = trajectory.world_from_cam[i1];
  return Rigid3d(a.rotation.slerp(alpha, b.rotation).normalized(),
                 (1.0 - alpha) * a.translation + alpha * b.translation);
}

std::optional<Eigen::Vector3d> accelerometer_at(const TumAccelerometer& accel, double t, double half_window_s,
                                                double max_gap_s) {
  const std::vector<double>& times = accel.time_s;
  const auto begin = std::lower_bound(times.begin(), times.end(), t - half_window_s);
  const auto end = std::upper_bound(times.begin(), times.end(), t + half_window_s);
  if (begin < end) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (auto it = begin; it != end; ++it) sum += accel.accel_mps2[static_cast<size_t>(it - times.begin())];
    return sum / static_cast<double>(end - begin);
  }
  // Empty window: the nearest reading.
  const auto after = std::lower_bound(times.begin(), times.end(), t);
  size_t best = times.size();
  double best_gap = max_gap_s;
  if (after != times.end() && *after - t <= best_gap) {
    best = static_cast<size_t>(after - times.begin());
    best_gap = *after - t;
  }
  if (after != times.begin() && t - *(after - 1) <= best_gap) best = static_cast<size_t>(after - times.begin()) - 1;
  if (best == times.size()) return std::nullopt;
  return accel.accel_mps2[best];
}

Eigen::Matrix3d tum_cam_from_accel() { return Eigen::Vector3d(-1.0, -1.0, 1.0).asDiagonal(); }

Camera parse_camera_line(const std::string& text) {
  std::istringstream in(text);
  std::string model;
  Camera camera;
  LMB_CHECK(in >> model >> camera.width >> camera.height,
            "--camera '" << text << "': expected MODEL WIDTH HEIGHT PARAMS...");
  camera.model = camera_model_from_name(model, "--camera");
  std::string token;
  while (in >> token) camera.params.push_back(parse_finite_number(token, "--camera", "parameter"));
  camera.check("--camera");
  return camera;
}

Eigen::Vector3d parse_axis(const std::string& text, const char* flag) {
  for (int k = 0; k < 6; ++k) {
    if (text == kAxisNames[k]) return axis_vector(k);
  }
  LMB_FAIL(flag << ": '" << text << "' is not an axis (expected +x, -x, +y, -y, +z or -z)");
}

void TumImportOptions::check() const {
  LMB_CHECK(!data_dirs.empty(), "--data: missing (at least one map sequence)");
  for (const auto& d : data_dirs) LMB_CHECK(!d.empty(), "--data: empty folder name");
  for (const auto& d : query_dirs) LMB_CHECK(!d.empty(), "--query-data: empty folder name");
  LMB_CHECK(session_names.empty() || session_names.size() == data_dirs.size() + query_dirs.size(),
            "--names: " << session_names.size() << " names for " << data_dirs.size() + query_dirs.size()
                        << " sequences (give one per sequence: --data ones first, then --query-data ones)");
  for (const std::string& n : session_names) check_session_name(n, "--names");
  LMB_CHECK(!out_dir.empty(), "--out: missing");
  LMB_CHECK(gravity == "accelerometer" || gravity == "groundtruth-up" || gravity == "none",
            "--gravity: '" << gravity << "' (expected accelerometer, groundtruth-up or none)");
  parse_axis(world_up, "--world-up");
  parse_camera_line(camera);
  parse_split_rule(split);
  LMB_CHECK(std::isfinite(time_offset_s) && std::abs(time_offset_s) <= 1.0,
            "--time-offset: " << time_offset_s << " s is not within [-1, 1] s");
  LMB_CHECK(max_gap_s > 0 && max_gap_s <= 1.0, "--max-gap: " << max_gap_s << " s is not within (0, 1] s");
  LMB_CHECK(accel_half_window_s >= 0 && accel_half_window_s <= 1.0,
            "--accel-window: " << accel_half_window_s << " s is not within [0, 1] s");
  LMB_CHECK(cam_from_accel.allFinite() &&
                (cam_from_accel * cam_from_accel.transpose() - Eigen::Matrix3d::Identity()).norm() < 1e-6 &&
                cam_from_accel.determinant() > 0,
            "cam_from_accel is not a rotation");
}

namespace {

// A sequence folder's name: the last non-empty path component.
std::string folder_name(const fs::path& dir) {
  const fs::path normal = fs::absolute(dir).lexically_normal();
  const std::string name = normal.filename().string();
  return name.empty() ? normal.parent_path().filename().string() : name;
}

// A kept frame: its listing, trajectory, interpolated pose and accelerometer reading.
struct Kept {
  const TumImage* image;
  const TumTrajectory* trajectory;
  Rigid3d world_from_cam;
  std::optional<Eigen::Vector3d> accel;
};

// How well the accelerometer's gravity agrees with the ground truth's over the kept frames with a
// reading (none: nullopt): angles, per world axis, a time-offset scan and the Kabsch-fitted rotation.
std::optional<GravityAgreement> gravity_agreement(const std::vector<Kept>& kept, const TumImportOptions& options,
                                                  const Eigen::Vector3d& up) {
  GravityAgreement g;
  std::vector<double> angles;
  std::vector<double> by_axis[6];
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();  // sum of (accel down) * (ground-truth down)^T
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> pairs;
  for (const Kept& k : kept) {
    if (!k.accel || k.accel->norm() < 1e-6) continue;
    const Eigen::Vector3d down_accel = (-*k.accel).normalized();
    const Eigen::Vector3d accel_in_cam = options.cam_from_accel * down_accel;
    const Eigen::Quaterniond cam_from_world = k.world_from_cam.rotation.conjugate();
    const Eigen::Vector3d truth = cam_from_world * (-up);
    angles.push_back(angle_deg(accel_in_cam, truth));
    for (int a = 0; a < 6; ++a) by_axis[a].push_back(angle_deg(accel_in_cam, cam_from_world * (-axis_vector(a))));
    h += down_accel * truth.transpose();
    pairs.emplace_back(down_accel, truth);
  }
  if (angles.empty()) return std::nullopt;
  g.frames = static_cast<int>(angles.size());
  g.median_deg = median(angles, 0.0);
  g.p90_deg = quantile(angles, 0.9, 0.0);
  double sum = 0;
  for (double a : angles) sum += a;
  g.mean_deg = sum / static_cast<double>(angles.size());
  for (int a = 0; a < 6; ++a) g.median_deg_by_world_axis[a] = median(by_axis[a], 0.0);
  // Time offset scan.
  g.best_time_offset_median_deg = 1e9;
  for (int step = -12; step <= 12; ++step) {
    const double offset = 0.005 * step;
    std::vector<double> scan;
    for (const Kept& k : kept) {
      if (!k.accel || k.accel->norm() < 1e-6) continue;
      const std::optional<Rigid3d> pose = interpolate_pose(*k.trajectory, k.image->time_s + offset, options.max_gap_s);
      if (!pose) continue;
      scan.push_back(angle_deg(options.cam_from_accel * (-*k.accel).normalized(), pose->rotation.conjugate() * (-up)));
    }
    const double m = median(scan, 0.0);
    if (!scan.empty() && m < g.best_time_offset_median_deg) {
      g.best_time_offset_median_deg = m;
      g.best_time_offset_s = offset;
    }
  }
  // Least-squares rotation (Kabsch): truth ~ R * down_accel.
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() > 0 ? 1.0 : -1.0;
  g.fitted_cam_from_accel = svd.matrixV() * d * svd.matrixU().transpose();
  g.fitted_rotation_offset_deg =
      Eigen::AngleAxisd(g.fitted_cam_from_accel * options.cam_from_accel.transpose()).angle() * kRadToDeg;
  std::vector<double> fitted;
  for (const auto& [down_accel, truth] : pairs)
    fitted.push_back(angle_deg(g.fitted_cam_from_accel * down_accel, truth));
  g.fitted_median_deg = median(fitted, 0.0);
  return g;
}

// The map/query split of one map sequence's kept frames by `rule` (a list rule over several map
// sequences: the entries naming this sequence's frames, added to *list_entries_used).
std::vector<bool> map_frame_flags(const SplitRule& rule, size_t num_map, const std::vector<Kept>& frames,
                                  const fs::path& dir, std::set<std::string>* list_entries_used) {
  std::vector<SplitFrame> split_frames;
  std::set<std::string> keys;
  for (const Kept& k : frames) {
    SplitFrame f;
    f.keys = {k.image->timestamp, k.image->file, fs::path(k.image->file).filename().string()};
    f.time_s = k.image->time_s;
    keys.insert(f.keys.begin(), f.keys.end());
    split_frames.push_back(f);
  }
  SplitRule sequence_rule = rule;
  if (rule.kind == SplitRule::Kind::kList && num_map > 1) {
    sequence_rule.list.clear();
    for (const std::string& e : rule.list) {
      if (!keys.count(e)) continue;
      sequence_rule.list.push_back(e);
      list_entries_used->insert(e);
    }
    // A map-list must give every map sequence map frames; a query-list may leave one all map.
    LMB_CHECK(!sequence_rule.list.empty() || rule.list_names_queries,
              rule.list_file.string() << ": names no frame of map sequence " << dir.string());
  }
  return assign_map_frames(sequence_rule, split_frames, true);
}

// The session name of each sequence folder: --names, or the folder's name ("map" for the one map
// sequence of a legacy import); each checked.
std::vector<std::string> sequence_names(const TumImportOptions& options, const std::vector<fs::path>& dirs,
                                        bool legacy_names) {
  std::vector<std::string> names = options.session_names;
  if (names.empty()) {
    for (const fs::path& d : dirs) names.push_back(legacy_names ? "map" : folder_name(d));
  }
  for (size_t i = 0; i < dirs.size(); ++i) {
    check_session_name(names[i], dirs[i].string() + ": session name (its folder's name; set --names)");
  }
  return names;
}

}  // namespace

TumImportStats import_tum(const TumImportOptions& options) {
  options.check();
  const Eigen::Vector3d up = parse_axis(options.world_up, "--world-up");
  const Camera camera = parse_camera_line(options.camera);
  const SplitRule rule = parse_split_rule(options.split);
  const size_t num_map = options.data_dirs.size();
  std::vector<fs::path> dirs = options.data_dirs;
  dirs.insert(dirs.end(), options.query_dirs.begin(), options.query_dirs.end());
  const bool legacy_names = options.session_names.empty() && num_map == 1 && options.query_dirs.empty();
  const std::vector<std::string> names = sequence_names(options, dirs, legacy_names);

  TumImportStats stats;
  // Every sequence's inputs stay alive until the end (Kept points into them).
  std::vector<std::vector<TumImage>> listed(dirs.size());
  std::vector<TumTrajectory> trajectories(dirs.size());
  std::vector<Kept> kept;
  std::vector<CollectionImage> images;
  std::set<std::string> list_entries_used;
  bool any_accel = false;
  for (size_t seq = 0; seq < dirs.size(); ++seq) {
    const fs::path& dir = dirs[seq];
    const bool map_sequence = seq < num_map;
    LMB_CHECK(fs::is_directory(dir), dir.string() << ": TUM sequence folder does not exist");
    listed[seq] = read_tum_image_list(dir / "rgb.txt");
    trajectories[seq] = read_tum_trajectory(dir / "groundtruth.txt");
    const bool has_accel = fs::exists(dir / "accelerometer.txt");
    LMB_CHECK(has_accel || options.gravity != "accelerometer", (dir / "accelerometer.txt").string()
                                                                   << ": missing (needed by --gravity accelerometer)");
    TumAccelerometer accel;
    if (has_accel) accel = read_tum_accelerometer(dir / "accelerometer.txt");
    any_accel = any_accel || has_accel;
    stats.listed_frames += static_cast<int>(listed[seq].size());

    const size_t first_kept = kept.size();
    int skipped_no_pose = 0;
    for (const TumImage& im : listed[seq]) {
      const std::optional<Rigid3d> pose =
          interpolate_pose(trajectories[seq], im.time_s + options.time_offset_s, options.max_gap_s);
      if (!pose) {
        ++skipped_no_pose;
        continue;
      }
      std::optional<Eigen::Vector3d> a;
      if (has_accel) a = accelerometer_at(accel, im.time_s, options.accel_half_window_s, options.max_gap_s);
      if (options.gravity == "accelerometer" && (!a || a->norm() < 1e-6)) {
        ++stats.skipped_no_accelerometer;
        continue;
      }
      LMB_CHECK(fs::is_regular_file(dir / im.file), (dir / im.file).string() << ": image listed in rgb.txt is missing");
      kept.push_back(Kept{&im, &trajectories[seq], *pose, a});
    }
    stats.skipped_no_pose += skipped_no_pose;
    LMB_CHECK(kept.size() > first_kept, dir.string()
                                            << ": no frame has ground truth within " << options.max_gap_s * 1000
                                            << " ms (" << skipped_no_pose << " skipped)");

    // The split: map sequences by the rule, query sequences all queries.
    std::vector<bool> is_map(kept.size() - first_kept, false);
    if (map_sequence) {
      const std::vector<Kept> frames(kept.begin() + static_cast<std::ptrdiff_t>(first_kept), kept.end());
      is_map = map_frame_flags(rule, num_map, frames, dir, &list_entries_used);
    }

    const std::string map_name = names[seq];
    const std::string query_name = !map_sequence ? names[seq] : legacy_names ? "query" : names[seq] + "-query";
    int map_count = 0, query_count = 0;
    for (size_t i = first_kept; i < kept.size(); ++i) {
      const Kept& k = kept[i];
      const bool m = is_map[i - first_kept];
      CollectionImage out;
      out.image.image_id = static_cast<int>(images.size()) + 1;
      out.image.camera_id = 1;
      out.image.name =
          (m ? map_name : query_name) + "/" + k.image->timestamp + fs::path(k.image->file).extension().string();
      out.image.cam_from_world = k.world_from_cam.inverse();
      out.source = dir / k.image->file;
      if (options.gravity == "accelerometer") {
        out.gravity_in_cam = (-(options.cam_from_accel * *k.accel)).normalized();
      } else if (options.gravity == "groundtruth-up") {
        out.gravity_in_cam = (out.image.cam_from_world.rotation * (-up)).normalized();
      }
      (m ? map_count : query_count) += 1;
      images.push_back(std::move(out));
    }
    stats.map_frames += map_count;
    stats.query_frames += query_count;
    auto add_session = [&](const std::string& name, SessionKind kind, int frames) {
      if (frames == 0) return;
      for (const MapSession& s : stats.sessions) {
        LMB_CHECK(s.name != name,
                  dir.string() << ": session name '" << name << "' is already used by another sequence (set --names)");
      }
      stats.sessions.push_back(MapSession{name, kind});
      stats.session_frames.push_back(frames);
    };
    add_session(map_name, SessionKind::kMap, map_count);
    add_session(query_name, SessionKind::kQuery, query_count);
  }
  if (rule.kind == SplitRule::Kind::kList && num_map > 1) {
    for (const std::string& e : rule.list) {
      LMB_CHECK(list_entries_used.count(e), rule.list_file.string()
                                                << ": entry '" << e << "' names no frame of the map sequences");
    }
  }
  stats.imported_frames = static_cast<int>(images.size());
  const bool has_accel = any_accel;

  // Gravity agreement between the accelerometer and the ground truth.
  if (has_accel) {
    if (std::optional<GravityAgreement> g = gravity_agreement(kept, options, up)) stats.gravity_agreement = *g;
  }

  std::map<int, Camera> cameras;
  cameras[1] = camera;
  write_collection(options.out_dir, cameras, images, options.overwrite, stats.sessions);
  return stats;
}

}  // namespace lmb
