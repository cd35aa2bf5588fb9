#include "train/import/sevenscenes_import.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <set>
#include <sstream>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <opencv2/imgcodecs.hpp>

#include "common/error.h"
#include "common/io/session_file.h"
#include "common/stats.h"
#include "common/text_lines.h"
#include "common/text_parse.h"
#include "train/import/collection_writer.h"

namespace lmb {

namespace fs = std::filesystem;

namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

bool all_digits(const std::string& s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isdigit(c) != 0; });
}

// "N" or "A-B" (digits only) into *first, *last; false for anything else.
bool parse_range(const std::string& text, int64_t* first, int64_t* last, const std::string& option,
                 const std::string& item) {
  const size_t dash = text.find('-');
  const std::string a = text.substr(0, dash);
  const std::string b = dash == std::string::npos ? a : text.substr(dash + 1);
  if (!all_digits(a) || !all_digits(b)) return false;
  LMB_CHECK(a.size() <= 9 && b.size() <= 9, option << ": '" << item << "': frame numbers have at most 9 digits");
  *first = std::stoll(a);
  *last = std::stoll(b);
  LMB_CHECK(*first <= *last, option << ": '" << item << "': the range ends before it starts");
  return true;
}

// The frame number of "frame-NNNNNN.color.png" (or .jpg, .jpeg) and its digits; false otherwise.
bool parse_image_name(const std::string& name, int64_t* number, std::string* digits) {
  static const std::string kPrefix = "frame-";
  if (name.compare(0, kPrefix.size(), kPrefix) != 0) return false;
  const size_t dot = name.find('.', kPrefix.size());
  if (dot == std::string::npos) return false;
  const std::string d = name.substr(kPrefix.size(), dot - kPrefix.size());
  const std::string rest = name.substr(dot);
  if (!all_digits(d) || d.size() > 9) return false;
  if (rest != ".color.png" && rest != ".color.jpg" && rest != ".color.jpeg") return false;
  *number = std::stoll(d);
  *digits = d;
  return true;
}

std::string frame_text(int64_t number) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%06lld", static_cast<long long>(number));
  return buf;
}

// A parsed number that may be inf or NaN (a lost track); throws for anything that is not a number.
double parse_pose_entry(const std::string& token, const std::string& where, int entry) {
  const char* begin = token.c_str();
  char* end = nullptr;
  const double v = std::strtod(begin, &end);
  LMB_CHECK(end != begin && *end == '\0',
            where << ": entry " << entry << " is not a number: '" << escape_control_bytes(token) << "'");
  return v;
}

// The frames of one recording: its image and pose folders and its images by frame number.
struct FrameFile {
  std::string digits;  // as written in the file name
  fs::path image;
};
struct Recording {
  std::string name;  // the sequence folder's name; empty for a single-recording folder
  fs::path folder, image_dir, pose_dir;
  std::map<int64_t, FrameFile> frames;
};

// Whether `folder` holds frames itself: an rgb/ folder or a frame image.
bool holds_frames(const fs::path& folder) {
  std::error_code ec;
  if (fs::is_directory(folder / "rgb", ec)) return true;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    int64_t number = 0;
    std::string digits;
    if (parse_image_name(it->path().filename().string(), &number, &digits)) return true;
  }
  return false;
}

Recording list_recording(const fs::path& folder, const std::string& name) {
  Recording r;
  r.name = name;
  r.folder = folder;
  std::error_code ec;
  r.image_dir = fs::is_directory(folder / "rgb", ec) ? folder / "rgb" : folder;
  r.pose_dir = fs::is_directory(folder / "pose", ec) ? folder / "pose" : r.image_dir;
  fs::directory_iterator it(r.image_dir, ec);
  LMB_CHECK(!ec, r.image_dir.string() << ": cannot list the folder: " << ec.message());
  for (fs::directory_iterator end; it != end; it.increment(ec)) {
    LMB_CHECK(!ec, r.image_dir.string() << ": cannot list the folder: " << ec.message());
    const std::string file = it->path().filename().string();
    int64_t number = 0;
    std::string digits;
    if (!parse_image_name(file, &number, &digits)) continue;
    const auto [at, inserted] = r.frames.emplace(number, FrameFile{digits, it->path()});
    LMB_CHECK(inserted, r.image_dir.string() << ": frame " << number << " has two images, "
                                             << at->second.image.filename().string() << " and " << file);
  }
  LMB_CHECK(!r.frames.empty(), r.image_dir.string() << ": no frame image (frame-NNNNNN.color.png or .jpg)");
  return r;
}

// A selected frame.
struct Selected {
  const Recording* recording;
  int64_t number;
  bool map;
};

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * kRadToDeg;
}

// A selected frame with a pose.
struct Kept {
  const Selected* frame;
  const FrameFile* file;
  Rigid3d world_from_cam;
};

}  // namespace

std::vector<FrameItem> parse_frame_items(const std::string& text, const std::string& option) {
  std::vector<FrameItem> items;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    const size_t b = item.find_first_not_of(" \t");
    const size_t e = item.find_last_not_of(" \t");
    item = b == std::string::npos ? "" : item.substr(b, e - b + 1);
    LMB_CHECK(!item.empty(), option << ": '" << text << "': an empty item (expected FIRST-LAST, N, a sequence "
                                    << "folder NAME or NAME:FIRST-LAST, separated by commas)");
    FrameItem f;
    f.text = item;
    const size_t colon = item.find(':');
    if (colon != std::string::npos) {
      f.sequence = item.substr(0, colon);
      const std::string range = item.substr(colon + 1);
      LMB_CHECK(!f.sequence.empty() && parse_range(range, &f.first, &f.last, option, item),
                option << ": '" << item << "': expected NAME:FIRST-LAST (e.g. seq-01:0-499)");
    } else if (!parse_range(item, &f.first, &f.last, option, item)) {
      f.sequence = item;
      f.all_frames = true;
    }
    items.push_back(f);
  }
  LMB_CHECK(!items.empty(), option << ": no frame named (expected e.g. 0-499 or seq-01)");
  return items;
}

std::optional<Rigid3d> read_sevenscenes_pose(const fs::path& path) {
  Eigen::Matrix4d m;
  int rows = 0;
  for (TextLineReader lines(path); lines.next();) {
    const std::vector<std::string> tokens = lines.tokens();
    ++rows;
    LMB_CHECK(rows <= 4, path.string() << ": expected 4 rows of 4 numbers (a 4x4 camera-to-world matrix), got more");
    LMB_CHECK(tokens.size() == 4,
              lines.where() << ": expected 4 numbers (a row of the 4x4 camera-to-world matrix), got " << tokens.size());
    for (int c = 0; c < 4; ++c) m(rows - 1, c) = parse_pose_entry(tokens[c], lines.where(), c + 1);
  }
  LMB_CHECK(rows == 4,
            path.string() << ": expected 4 rows of 4 numbers (a 4x4 camera-to-world matrix), got " << rows << " rows");
  if (!m.allFinite()) return std::nullopt;
  LMB_CHECK(m.row(3) == Eigen::RowVector4d(0, 0, 0, 1), path.string() << ": last row is " << m(3, 0) << ' ' << m(3, 1)
                                                                      << ' ' << m(3, 2) << ' ' << m(3, 3)
                                                                      << ", expected 0 0 0 1 (a rigid transform)");
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  const double deviation = (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  LMB_CHECK(deviation <= kPoseOrthonormalTolerance,
            path.string() << ": the rotation block is not a rotation (largest entry of R^T R - I is " << deviation
                          << ", tolerance " << kPoseOrthonormalTolerance << ")");
  LMB_CHECK(r.determinant() > 0, path.string()
                                     << ": the rotation block is a reflection (determinant " << r.determinant() << ")");
  // The nearest rotation (the poses of tracking carry rounding of a few 1e-4).
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(r, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d rotation = svd.matrixU() * svd.matrixV().transpose();
  return Rigid3d(Eigen::Quaterniond(rotation).normalized(), m.block<3, 1>(0, 3));
}

Eigen::Matrix3d read_intrinsics_matrix(const fs::path& path) {
  Eigen::Matrix3d k;
  int rows = 0;
  for (TextLineReader lines(path); lines.next();) {
    const std::vector<std::string> tokens = lines.tokens();
    ++rows;
    LMB_CHECK(rows <= 3, path.string() << ": expected 3 rows of 3 numbers (a 3x3 camera matrix K), got more");
    LMB_CHECK(tokens.size() == 3, lines.where()
                                      << ": expected 3 numbers (a row of the camera matrix K), got " << tokens.size());
    for (int c = 0; c < 3; ++c) {
      k(rows - 1, c) = parse_finite_number(tokens[c], lines.where(),
                                           "K(" + std::to_string(rows) + "," + std::to_string(c + 1) + ")");
    }
  }
  LMB_CHECK(rows == 3,
            path.string() << ": expected 3 rows of 3 numbers (a 3x3 camera matrix K), got " << rows << " rows");
  LMB_CHECK(k.row(2) == Eigen::RowVector3d(0, 0, 1),
            path.string() << ": last row is " << k(2, 0) << ' ' << k(2, 1) << ' ' << k(2, 2) << ", expected 0 0 1");
  LMB_CHECK(k(1, 0) == 0, path.string() << ": K(2,1) is " << k(1, 0) << ", expected 0");
  LMB_CHECK(k(0, 1) == 0,
            path.string() << ": skew K(1,2) is " << k(0, 1) << "; only a camera matrix without skew is supported");
  LMB_CHECK(k(0, 0) > 0 && k(1, 1) > 0,
            path.string() << ": focal lengths fx = " << k(0, 0) << ", fy = " << k(1, 1) << " must be > 0");
  return k;
}

Eigen::Vector3d read_world_vector(const fs::path& path) {
  std::vector<std::string> tokens;
  for (TextLineReader lines(path); lines.next();) {
    for (const std::string& t : lines.tokens()) tokens.push_back(t);
  }
  LMB_CHECK(tokens.size() == 3, path.string() << ": expected 3 numbers (a world-frame vector), got " << tokens.size());
  Eigen::Vector3d v;
  for (int i = 0; i < 3; ++i)
    v[i] = parse_finite_number(tokens[i], path.string(), "component " + std::to_string(i + 1));
  LMB_CHECK(v.norm() > 0 && std::isfinite(v.norm()),
            path.string() << ": the vector has no direction (length " << v.norm() << ")");
  return v.normalized();
}

void SevenScenesImportOptions::check() const {
  LMB_CHECK(!data_dir.empty(), "--data: missing");
  LMB_CHECK(!out_dir.empty(), "--out: missing");
  LMB_CHECK(!map_frames.empty(), "--map-frames: missing (e.g. 0-499, or seq-01)");
  parse_frame_items(map_frames, "--map-frames");
  if (!query_frames.empty()) parse_frame_items(query_frames, "--query-frames");
  LMB_CHECK(stride >= 1, "--stride: " << stride << " must be >= 1");
  LMB_CHECK(intrinsics_file.empty() || !focal, "--intrinsics and --focal are exclusive (give the camera one way)");
  LMB_CHECK(focal || (!cx && !cy), "--cx and --cy need --focal");
  LMB_CHECK(!focal || (std::isfinite(*focal) && *focal > 0), "--focal: " << *focal << " must be finite and > 0");
  LMB_CHECK(!cx || std::isfinite(*cx), "--cx: " << *cx << " is not finite");
  LMB_CHECK(!cy || std::isfinite(*cy), "--cy: " << *cy << " is not finite");
  LMB_CHECK(gravity.empty() || !gravity_up, "--gravity and --gravity-up are exclusive");
  LMB_CHECK(!gravity_up || (gravity_up->allFinite() && gravity_up->norm() > 0),
            "--gravity-up: expected a finite, non-zero vector X Y Z");
}

namespace {

// The selected frames' poses; a non-finite one skips its frame (counted in `stats`). Throws when a
// pose file is missing or malformed, or when every frame of a kind is skipped.
std::vector<Kept> read_poses(const std::vector<Selected>& selected, const SevenScenesImportOptions& options,
                             SevenScenesImportStats* out) {
  SevenScenesImportStats& stats = *out;
  std::vector<Kept> kept;
  int selected_map = 0, selected_query = 0;
  for (const Selected& s : selected) {
    (s.map ? selected_map : selected_query) += 1;
    const FrameFile& file = s.recording->frames.at(s.number);
    const fs::path pose_path = s.recording->pose_dir / ("frame-" + file.digits + ".pose.txt");
    LMB_CHECK(fs::exists(pose_path), pose_path.string() << ": missing (the pose of " << file.image.string() << ")");
    const std::optional<Rigid3d> pose = read_sevenscenes_pose(pose_path);
    if (!pose) {
      ++stats.skipped_invalid_pose;
      stats.skipped_poses.push_back(pose_path.string());
      continue;
    }
    kept.push_back(Kept{&s, &file, *pose});
  }
  int kept_map = 0, kept_query = 0;
  for (const Kept& k : kept) (k.frame->map ? kept_map : kept_query) += 1;
  LMB_CHECK(kept_map > 0, "--map-frames '" << options.map_frames << "': all " << selected_map
                                           << " selected frames have a non-finite pose (skipped)");
  LMB_CHECK(selected_query == 0 || kept_query > 0, "--query-frames '" << options.query_frames << "': all "
                                                                      << selected_query
                                                                      << " selected frames have a non-finite pose "
                                                                         "(skipped)");

  return kept;
}

// The camera: its size from the first kept image of each recording (all must agree), its matrix
// from --intrinsics, --focal or DATA/camera-intrinsics.txt (`source` says which).
Camera camera_of(const std::vector<Kept>& kept, const SevenScenesImportOptions& options, std::string* source) {
  const fs::path& dir = options.data_dir;
  int width = 0, height = 0;
  fs::path first_image;
  std::set<const Recording*> sized;
  for (const Kept& k : kept) {
    if (!sized.insert(k.frame->recording).second) continue;
    const cv::Mat image = cv::imread(k.file->image.string(), cv::IMREAD_GRAYSCALE);
    LMB_CHECK(!image.empty(), k.file->image.string() << ": cannot decode the image");
    if (first_image.empty()) {
      width = image.cols;
      height = image.rows;
      first_image = k.file->image;
    }
    LMB_CHECK(image.cols == width && image.rows == height,
              k.file->image.string() << " is " << image.cols << "x" << image.rows << " pixels, but "
                                     << first_image.string() << " is " << width << "x" << height
                                     << " (one camera for all frames)");
  }
  Eigen::Matrix3d k = Eigen::Matrix3d::Identity();
  const fs::path default_intrinsics = dir / "camera-intrinsics.txt";
  if (!options.intrinsics_file.empty()) {
    k = read_intrinsics_matrix(options.intrinsics_file);
    *source = options.intrinsics_file.string();
  } else if (options.focal) {
    k(0, 0) = k(1, 1) = *options.focal;
    k(0, 2) = options.cx ? *options.cx : 0.5 * width;
    k(1, 2) = options.cy ? *options.cy : 0.5 * height;
    *source = "--focal";
    std::string centred;  // the coordinates of the principal point taken from the image centre
    if (options.cx) *source += ", --cx";
    if (options.cy) *source += ", --cy";
    if (!options.cx) centred = "cx";
    if (!options.cy) centred += centred.empty() ? "cy" : ", cy";
    if (!centred.empty()) *source += " (" + centred + ": the image centre)";
    if (fs::exists(default_intrinsics)) *source += " (instead of " + default_intrinsics.string() + ")";
  } else {
    LMB_CHECK(fs::exists(default_intrinsics),
              dir.string() << ": no camera intrinsics (" << default_intrinsics.string()
                           << " is missing); give --intrinsics FILE (a 3x3 K) or --focal F [--cx CX --cy CY]");
    k = read_intrinsics_matrix(default_intrinsics);
    *source = default_intrinsics.string();
  }
  Camera camera;
  camera.model = CameraModel::kPinhole;
  camera.width = width;
  camera.height = height;
  camera.params = {k(0, 0), k(1, 1), k(0, 2), k(1, 2)};
  camera.check(*source);
  return camera;
}

// The world's down direction: --gravity-up, --gravity FILE|none, or DATA/gravity-direction.txt.
void gravity_of(const SevenScenesImportOptions& options, SevenScenesImportStats* out) {
  SevenScenesImportStats& stats = *out;
  const fs::path& dir = options.data_dir;
  const fs::path default_gravity = dir / "gravity-direction.txt";
  if (options.gravity_up) {
    stats.gravity_down_world = Eigen::Vector3d::Zero() - options.gravity_up->normalized();  // no -0
    stats.gravity_source = "--gravity-up";
  } else if (options.gravity == "none") {
    stats.gravity_source = "none (--gravity none)";
  } else if (!options.gravity.empty()) {
    stats.gravity_down_world = read_world_vector(options.gravity);
    stats.gravity_source = options.gravity;
  } else if (fs::exists(default_gravity)) {
    stats.gravity_down_world = read_world_vector(default_gravity);
    stats.gravity_source = default_gravity.string();
  } else {
    stats.gravity_source = "none (no " + default_gravity.string() + ")";
  }
}

// The collection's images of the kept frames and their sessions: map and query for one recording;
// one a sequence folder (NAME-query for the query frames of a sequence that also has map frames)
// otherwise.
std::vector<CollectionImage> collection_images(const std::vector<Kept>& kept, bool single, const fs::path& dir,
                                               SevenScenesImportStats* stats_out) {
  SevenScenesImportStats& stats = *stats_out;
  std::set<std::string> map_sequences;
  for (const Kept& kf : kept) {
    if (kf.frame->map) map_sequences.insert(kf.frame->recording->name);
  }
  const auto session_of = [&](const Selected& s) -> std::string {
    if (single) return s.map ? "map" : "query";
    const std::string& name = s.recording->name;
    return s.map || !map_sequences.count(name) ? name : name + "-query";
  };
  std::vector<CollectionImage> images;
  std::vector<double> down_angles;
  for (const Kept& kf : kept) {
    const std::string session = session_of(*kf.frame);
    size_t index = 0;
    while (index < stats.sessions.size() && stats.sessions[index].name != session) ++index;
    if (index == stats.sessions.size()) {
      check_session_name(session, (dir / kf.frame->recording->name).string() + ": session name (the folder's name)");
      stats.sessions.push_back(MapSession{session, kf.frame->map ? SessionKind::kMap : SessionKind::kQuery});
      stats.session_frames.push_back(0);
    }
    ++stats.session_frames[index];
    CollectionImage out;
    out.image.image_id = static_cast<int>(images.size()) + 1;
    out.image.camera_id = 1;
    out.image.name = session + "/" + kf.file->image.filename().string();
    out.image.cam_from_world = kf.world_from_cam.inverse();
    out.source = kf.file->image;
    if (stats.gravity_down_world) {
      out.gravity_in_cam = (out.image.cam_from_world.rotation * *stats.gravity_down_world).normalized();
      down_angles.push_back(
          angle_deg(kf.world_from_cam.rotation * Eigen::Vector3d::UnitY(), *stats.gravity_down_world));
    }
    (kf.frame->map ? stats.map_frames : stats.query_frames) += 1;
    images.push_back(std::move(out));
  }
  stats.imported_frames = static_cast<int>(images.size());
  if (!down_angles.empty()) {
    stats.image_down_median_deg = median(down_angles);
    stats.image_down_p10_deg = quantile(down_angles, 0.1);
    stats.image_down_p90_deg = quantile(down_angles, 0.9);
  }

  return images;
}

}  // namespace

SevenScenesImportStats import_sevenscenes(const SevenScenesImportOptions& options) {
  options.check();
  const fs::path& dir = options.data_dir;
  LMB_CHECK(fs::is_directory(dir), dir.string() << ": the data folder does not exist");
  SevenScenesImportStats stats;

  // The layout: one recording, or sequence folders.
  std::map<std::string, Recording> recordings;  // by sequence name ("" for one recording)
  std::vector<std::string> sequence_names;
  const bool single = holds_frames(dir);
  if (single) {
    stats.layout = fs::is_directory(dir / "rgb") ? "rgb/ and pose/ folders" : "frames in the folder";
  } else {
    std::error_code ec;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
      if (it->is_directory(ec) && holds_frames(it->path())) sequence_names.push_back(it->path().filename().string());
    }
    std::sort(sequence_names.begin(), sequence_names.end());
    LMB_CHECK(!sequence_names.empty(),
              dir.string() << ": no frames (expected rgb/frame-NNNNNN.color.png or .jpg, such frames in the folder, "
                              "or sequence folders such as seq-01/ holding them)");
    stats.layout = "sequence folders";
  }
  std::string held;
  for (size_t i = 0; i < sequence_names.size() && i < 4; ++i) held += (i ? ", " : "") + sequence_names[i];
  if (sequence_names.size() > 4) held += ", ...";
  const auto recording = [&](const FrameItem& item, const std::string& option) -> const Recording& {
    if (single) {
      LMB_CHECK(item.sequence.empty(), option << ": '" << item.text << "': " << dir.string()
                                              << " holds one recording, not sequence folders; give frame numbers "
                                                 "such as 0-499");
    } else {
      LMB_CHECK(!item.sequence.empty(), option << ": '" << item.text << "': " << dir.string()
                                               << " holds sequence folders (" << held
                                               << "); name them: NAME or NAME:FIRST-LAST");
      LMB_CHECK(std::binary_search(sequence_names.begin(), sequence_names.end(), item.sequence),
                option << ": '" << item.text << "': " << (dir / item.sequence).string()
                       << " is not a sequence folder with frames (" << dir.string() << " holds " << held << ")");
    }
    auto it = recordings.find(item.sequence);
    if (it == recordings.end()) {
      it = recordings.emplace(item.sequence, list_recording(single ? dir : dir / item.sequence, item.sequence)).first;
    }
    return it->second;
  };

  // The selection, map items first: each frame at most once.
  std::vector<Selected> selected;
  std::map<std::pair<std::string, int64_t>, std::string> chosen_by;  // -> the option that chose it
  const auto select = [&](const std::string& text, const std::string& option, bool map) {
    for (const FrameItem& item : parse_frame_items(text, option)) {
      const Recording& r = recording(item, option);
      std::vector<int64_t> numbers;
      if (item.all_frames) {
        int64_t k = 0;
        for (const auto& [number, file] : r.frames) {
          if (k++ % options.stride == 0) numbers.push_back(number);
        }
      } else {
        for (int64_t n = item.first; n <= item.last; n += options.stride) {
          LMB_CHECK(r.frames.count(n), option << ": '" << item.text << "': frame " << n << " has no image in "
                                              << r.image_dir.string() << " (frame-" << frame_text(n)
                                              << ".color.png or .jpg)");
          numbers.push_back(n);
        }
      }
      for (int64_t n : numbers) {
        const auto [at, inserted] = chosen_by.emplace(std::make_pair(r.name, n), option);
        LMB_CHECK(inserted, option << ": '" << item.text << "': frame " << n << (r.name.empty() ? "" : " of " + r.name)
                                   << " is selected twice"
                                   << (at->second == option ? "" : " (also by " + at->second + ")"));
        selected.push_back(Selected{&r, n, map});
      }
    }
  };
  select(options.map_frames, "--map-frames", true);
  if (!options.query_frames.empty()) select(options.query_frames, "--query-frames", false);
  stats.selected_frames = static_cast<int>(selected.size());

  // Poses: a non-finite one skips its frame.
  const std::vector<Kept> kept = read_poses(selected, options, &stats);
  // The camera: its size from the first kept image of each recording (all must agree).
  stats.camera = camera_of(kept, options, &stats.camera_source);
  // Gravity: the world's down direction.
  gravity_of(options, &stats);
  // Sessions and the collection's images.
  const std::vector<CollectionImage> images = collection_images(kept, single, dir, &stats);
  std::map<int, Camera> cameras;
  cameras[1] = stats.camera;
  write_collection(options.out_dir, cameras, images, options.overwrite, stats.sessions);
  return stats;
}

}  // namespace lmb
