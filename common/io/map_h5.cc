#include "common/io/map_h5.h"

#include <cmath>
#include <cstring>
#include <system_error>
#include <vector>

#include "common/error.h"
#include "common/file_io.h"
#include "common/io/h5_util.h"

namespace lmb {

namespace fs = std::filesystem;

namespace {

constexpr int kMaxCameraParams = 12;  // FULL_OPENCV has the most parameters

using namespace h5;

bool finite3(const Eigen::Vector3d& v) { return v.allFinite(); }

void write_strings(H5::Group& group, const char* name, const std::vector<const char*>& strings) {
  H5::StrType str_type(H5::PredType::C_S1, H5T_VARIABLE);
  const hsize_t dims[1] = {strings.size()};
  H5::DataSet ds = group.createDataSet(name, str_type, H5::DataSpace(1, dims), untimed_dataset());
  if (!strings.empty()) ds.write(strings.data(), str_type);
  ds.close();
}

}  // namespace

void validate_landmark_map(const LandmarkMap& map, const std::string& where) {
  LMB_CHECK(map.descriptor_bytes >= 0 && map.descriptor_bytes <= 4096,
            where << ": descriptor_bytes: " << map.descriptor_bytes << " outside 0..4096");
  LMB_CHECK(!map.detector.empty(), where << ": detector: empty name");
  for (size_t c = 0; c < map.cameras.size(); ++c) {
    map.cameras[c].check(where + ": cameras[" + std::to_string(c) + "]");
  }
  LMB_CHECK(map.frames.empty() || !map.sessions.empty(),
            where << ": sessions: none, but " << map.frames.size() << " frames (every frame belongs to a session)");
  for (size_t s = 0; s < map.sessions.size(); ++s) {
    const MapSession& session = map.sessions[s];
    const std::string at = where + ": sessions[" + std::to_string(s) + "]";
    LMB_CHECK(!session.name.empty() && session.name.find_first_of(" \t\r\n") == std::string::npos,
              at << ".name: '" << session.name << "' is empty or contains white space");
    LMB_CHECK(session.kind == SessionKind::kMap || session.kind == SessionKind::kQuery ||
                  session.kind == SessionKind::kOutside,
              at << ".kind: " << static_cast<int>(session.kind) << " is not 0 (map), 1 (query) or 2 (outside)");
    for (size_t t = 0; t < s; ++t) {
      LMB_CHECK(map.sessions[t].name != session.name,
                at << ".name: '" << session.name << "' is also the name of sessions[" << t << "]");
    }
  }
  const int64_t num_keypoints = static_cast<int64_t>(map.keypoints.size());
  int64_t next_keypoint = 0;
  for (size_t f = 0; f < map.frames.size(); ++f) {
    const MapFrame& frame = map.frames[f];
    const std::string at = where + ": frames[" + std::to_string(f) + "]";
    LMB_CHECK(!frame.name.empty(), at << ".name: empty");
    LMB_CHECK(frame.camera >= 0 && frame.camera < static_cast<camera_t>(map.cameras.size()),
              at << ".camera: " << frame.camera << " outside 0.." << map.cameras.size());
    LMB_CHECK(frame.session >= 0 && frame.session < static_cast<int32_t>(map.sessions.size()),
              at << ".session: " << frame.session << " outside 0.." << map.sessions.size() - 1);
    const SessionKind kind = map.sessions[static_cast<size_t>(frame.session)].kind;
    LMB_CHECK(frame.is_query == (kind != SessionKind::kMap),
              at << ".is_query: " << frame.is_query << ", but its session '"
                 << map.sessions[static_cast<size_t>(frame.session)].name << "' is a " << session_kind_name(kind)
                 << " session (is_query must be 1 exactly for frames outside map sessions)");
    const Eigen::Quaterniond& q = frame.cam_from_world.rotation;
    LMB_CHECK(q.coeffs().allFinite() && std::abs(q.norm() - 1.0) < 1e-6,
              at << ".cam_from_world_q: not a rotation (norm " << q.norm() << ")");
    LMB_CHECK(finite3(frame.cam_from_world.translation), at << ".cam_from_world_t: not finite");
    LMB_CHECK(finite3(frame.gravity_in_cam) && std::abs(frame.gravity_in_cam.norm() - 1.0) < 1e-6,
              at << ".gravity_in_cam: not a unit vector");
    LMB_CHECK(frame.num_keypoints >= 0, at << ".num_keypoints: negative");
    LMB_CHECK(frame.first_keypoint == next_keypoint, at << ".first_keypoint: " << frame.first_keypoint << ", expected "
                                                        << next_keypoint
                                                        << " (frames' keypoint ranges must follow each other)");
    next_keypoint += frame.num_keypoints;
  }
  LMB_CHECK(next_keypoint == num_keypoints, where << ": frames.num_keypoints: sum " << next_keypoint
                                                  << " differs from the keypoint count " << num_keypoints);
  LMB_CHECK(static_cast<int64_t>(map.descriptors.size()) == num_keypoints * map.descriptor_bytes,
            where << ": descriptors: " << map.descriptors.size() << " bytes, expected " << num_keypoints << " x "
                  << map.descriptor_bytes);
  LMB_CHECK(static_cast<int64_t>(map.keypoint_landmark.size()) == num_keypoints,
            where << ": keypoint_landmark: " << map.keypoint_landmark.size() << " entries, expected " << num_keypoints);
  for (int64_t k = 0; k < num_keypoints; ++k) {
    const Keypoint& kp = map.keypoints[k];
    LMB_CHECK(std::isfinite(kp.x) && std::isfinite(kp.y) && std::isfinite(kp.scale) && std::isfinite(kp.angle),
              where << ": keypoints[" << k << "]: not finite");
  }
  const int64_t num_landmarks = static_cast<int64_t>(map.landmarks.size());
  std::vector<int32_t> map_obs(num_landmarks, 0), query_obs(num_landmarks, 0);
  for (const MapFrame& frame : map.frames) {
    for (int64_t k = frame.first_keypoint; k < frame.first_keypoint + frame.num_keypoints; ++k) {
      const landmark_t l = map.keypoint_landmark[k];
      LMB_CHECK(l == kInvalidLandmarkId || (l >= 0 && l < num_landmarks),
                where << ": keypoint_landmark[" << k << "]: " << l << " outside -1.." << num_landmarks - 1);
      LMB_CHECK(
          l == kInvalidLandmarkId || map.sessions[static_cast<size_t>(frame.session)].kind != SessionKind::kOutside,
          where << ": keypoint_landmark[" << k << "]: " << l << ", but its frame '" << frame.name
                << "' is in an outside session (recorded where the map has no landmarks)");
      if (l >= 0) ++(frame.is_query ? query_obs : map_obs)[l];
    }
  }
  for (int64_t l = 0; l < num_landmarks; ++l) {
    const Landmark& lm = map.landmarks[l];
    const std::string at = where + ": landmarks[" + std::to_string(l) + "]";
    LMB_CHECK(finite3(lm.position), at << ".position: not finite");
    LMB_CHECK(std::isfinite(lm.quality), at << ".quality: not finite");
    LMB_CHECK(std::isfinite(lm.mean_reprojection_error) && lm.mean_reprojection_error >= 0,
              at << ".mean_reprojection_error: not a finite non-negative number");
    LMB_CHECK(lm.num_map_observations == map_obs[l], at << ".num_map_observations: " << lm.num_map_observations
                                                        << ", but " << map_obs[l] << " map keypoints refer to it");
    LMB_CHECK(lm.num_query_observations == query_obs[l], at << ".num_query_observations: " << lm.num_query_observations
                                                            << ", but " << query_obs[l]
                                                            << " query keypoints refer to it");
  }
}

void write_map_h5(const LandmarkMap& map, const fs::path& path) {
  validate_landmark_map(map, path.string() + " (map to write)");
  H5::Exception::dontPrint();
  try {
    write_h5_atomically(path, [&](H5::H5File& file) {
      write_string_attribute(file, "format", kMapH5Format);
      write_int_attribute(file, "format_version", kMapH5Version);
      write_string_attribute(file, "detector", map.detector);
      write_int_attribute(file, "descriptor_bytes", map.descriptor_bytes);

      const hsize_t num_cameras = map.cameras.size();
      std::vector<int32_t> model, width, height;
      std::vector<double> params(num_cameras * kMaxCameraParams, 0.0);
      for (size_t c = 0; c < num_cameras; ++c) {
        const Camera& cam = map.cameras[c];
        model.push_back(static_cast<int32_t>(cam.model));
        width.push_back(cam.width);
        height.push_back(cam.height);
        for (size_t p = 0; p < cam.params.size(); ++p) params[c * kMaxCameraParams + p] = cam.params[p];
      }
      H5::Group cameras = create_untimed_group(file, "/cameras");
      write_column(cameras, "model", model, num_cameras);
      write_column(cameras, "width", width, num_cameras);
      write_column(cameras, "height", height, num_cameras);
      write_column(cameras, "params", params, num_cameras, kMaxCameraParams);

      const hsize_t num_sessions = map.sessions.size();
      std::vector<const char*> session_names;
      std::vector<uint8_t> session_kind;
      for (const MapSession& s : map.sessions) {
        session_names.push_back(s.name.c_str());
        session_kind.push_back(static_cast<uint8_t>(s.kind));
      }
      H5::Group sessions = create_untimed_group(file, "/sessions");
      write_strings(sessions, "name", session_names);
      write_column(sessions, "kind", session_kind, num_sessions);

      const hsize_t num_frames = map.frames.size();
      std::vector<const char*> names;
      std::vector<int32_t> camera, session, num_keypoints;
      std::vector<double> q, t, gravity;
      std::vector<uint8_t> is_query;
      std::vector<int64_t> first_keypoint;
      for (const MapFrame& f : map.frames) {
        names.push_back(f.name.c_str());
        camera.push_back(f.camera);
        session.push_back(f.session);
        const Eigen::Quaterniond& r = f.cam_from_world.rotation;
        q.insert(q.end(), {r.w(), r.x(), r.y(), r.z()});
        const Eigen::Vector3d& tr = f.cam_from_world.translation;
        t.insert(t.end(), {tr.x(), tr.y(), tr.z()});
        gravity.insert(gravity.end(), {f.gravity_in_cam.x(), f.gravity_in_cam.y(), f.gravity_in_cam.z()});
        is_query.push_back(f.is_query ? 1 : 0);
        first_keypoint.push_back(f.first_keypoint);
        num_keypoints.push_back(f.num_keypoints);
      }
      H5::Group frames = create_untimed_group(file, "/frames");
      write_strings(frames, "name", names);
      write_column(frames, "camera", camera, num_frames);
      write_column(frames, "session", session, num_frames);
      write_column(frames, "cam_from_world_q", q, num_frames, 4);
      write_column(frames, "cam_from_world_t", t, num_frames, 3);
      write_column(frames, "gravity_in_cam", gravity, num_frames, 3);
      write_column(frames, "is_query", is_query, num_frames);
      write_column(frames, "first_keypoint", first_keypoint, num_frames);
      write_column(frames, "num_keypoints", num_keypoints, num_frames);

      const hsize_t n = map.keypoints.size();
      std::vector<float> xy, scale, angle;
      xy.reserve(2 * n);
      for (const Keypoint& k : map.keypoints) {
        xy.push_back(k.x);
        xy.push_back(k.y);
        scale.push_back(k.scale);
        angle.push_back(k.angle);
      }
      H5::Group keypoints = create_untimed_group(file, "/keypoints");
      write_column(keypoints, "xy", xy, n, 2);
      write_column(keypoints, "scale", scale, n);
      write_column(keypoints, "angle", angle, n);
      write_column(keypoints, "descriptors", map.descriptors, n, static_cast<hsize_t>(map.descriptor_bytes));
      write_column(keypoints, "landmark", map.keypoint_landmark, n);

      const hsize_t num_landmarks = map.landmarks.size();
      std::vector<double> position;
      std::vector<float> quality, reprojection;
      std::vector<int32_t> map_obs, query_obs;
      for (const Landmark& l : map.landmarks) {
        position.insert(position.end(), {l.position.x(), l.position.y(), l.position.z()});
        quality.push_back(l.quality);
        reprojection.push_back(l.mean_reprojection_error);
        map_obs.push_back(l.num_map_observations);
        query_obs.push_back(l.num_query_observations);
      }
      H5::Group landmarks = create_untimed_group(file, "/landmarks");
      write_column(landmarks, "position", position, num_landmarks, 3);
      write_column(landmarks, "quality", quality, num_landmarks);
      write_column(landmarks, "mean_reprojection_error", reprojection, num_landmarks);
      write_column(landmarks, "num_map_observations", map_obs, num_landmarks);
      write_column(landmarks, "num_query_observations", query_obs, num_landmarks);
    });
  } catch (const H5::Exception& e) {
    LMB_FAIL(path.string() << ": cannot write HDF5: " << e.getFuncName() << ": " << e.getDetailMsg());
  }
}

LandmarkMap read_map_h5(const fs::path& path) {
  H5::Exception::dontPrint();
  const std::string name = path.string();
  std::error_code ec;
  LMB_CHECK(fs::is_regular_file(path, ec), name << ": no such file");
  LandmarkMap map;
  try {
    LMB_CHECK(H5::H5File::isHdf5(name), name << ": not an HDF5 file (expected a landmarkboost-map)");
    H5::H5File file;
    try {
      file.openFile(name, H5F_ACC_RDONLY);
    } catch (const H5::Exception& e) {
      LMB_FAIL(name << ": cannot open as HDF5 (truncated or damaged file): " << e.getDetailMsg());
    }
    Reader r(path, file);
    const std::string format = r.string_attribute("format");
    LMB_CHECK(format == kMapH5Format, name << ": attribute 'format': '" << format
                                           << "' is not a landmark map (expected '" << kMapH5Format << "')");
    const int64_t version = r.int_attribute("format_version");
    LMB_CHECK(version == 1 || version == kMapH5Version, name << ": attribute 'format_version': version " << version
                                                             << " is not supported (this build reads versions 1 and "
                                                             << kMapH5Version << ")");
    map.detector = r.string_attribute("detector");
    const int64_t descriptor_bytes = r.int_attribute("descriptor_bytes");
    LMB_CHECK(descriptor_bytes >= 0 && descriptor_bytes <= 4096,
              name << ": attribute 'descriptor_bytes': " << descriptor_bytes << " outside 0..4096");
    map.descriptor_bytes = static_cast<int>(descriptor_bytes);

    int64_t num_cameras = 0;
    const auto model = r.column<int32_t>("/cameras/model", -1, 1, -1, &num_cameras);
    const auto width = r.column<int32_t>("/cameras/width", num_cameras);
    const auto height = r.column<int32_t>("/cameras/height", num_cameras);
    const auto params = r.column<double>("/cameras/params", num_cameras, 2, kMaxCameraParams);
    for (int64_t c = 0; c < num_cameras; ++c) {
      Camera cam;
      try {
        cam.model = camera_model_from_id(model[c]);
      } catch (const Error& e) {
        LMB_FAIL(name << ": /cameras/model[" << c << "]: " << e.what());
      }
      cam.width = width[c];
      cam.height = height[c];
      const int np = camera_model_num_params(cam.model);
      cam.params.assign(params.begin() + c * kMaxCameraParams, params.begin() + c * kMaxCameraParams + np);
      map.cameras.push_back(cam);
    }

    // Version 1 has no sessions: its frames become the sessions "map" and "query" (below).
    std::vector<int32_t> session;
    if (version >= 2) {
      int64_t num_sessions = 0;
      const auto kind = r.column<uint8_t>("/sessions/kind", -1, 1, -1, &num_sessions);
      const auto session_names = r.strings("/sessions/name", num_sessions);
      for (int64_t s = 0; s < num_sessions; ++s) {
        LMB_CHECK(kind[s] <= 2, name << ": /sessions/kind[" << s << "]: " << int(kind[s])
                                     << " is not 0 (map), 1 (query) or 2 (outside)");
        map.sessions.push_back(MapSession{session_names[s], static_cast<SessionKind>(kind[s])});
      }
    }
    int64_t num_frames = 0;
    const auto camera = r.column<int32_t>("/frames/camera", -1, 1, -1, &num_frames);
    if (version >= 2) session = r.column<int32_t>("/frames/session", num_frames);
    const auto names = r.strings("/frames/name", num_frames);
    const auto q = r.column<double>("/frames/cam_from_world_q", num_frames, 2, 4);
    const auto t = r.column<double>("/frames/cam_from_world_t", num_frames, 2, 3);
    const auto gravity = r.column<double>("/frames/gravity_in_cam", num_frames, 2, 3);
    const auto is_query = r.column<uint8_t>("/frames/is_query", num_frames);
    const auto first_keypoint = r.column<int64_t>("/frames/first_keypoint", num_frames);
    const auto num_keypoints = r.column<int32_t>("/frames/num_keypoints", num_frames);
    for (int64_t f = 0; f < num_frames; ++f) {
      MapFrame frame;
      frame.name = names[f];
      frame.camera = camera[f];
      if (version >= 2) frame.session = session[f];
      frame.cam_from_world.rotation = Eigen::Quaterniond(q[4 * f], q[4 * f + 1], q[4 * f + 2], q[4 * f + 3]);
      frame.cam_from_world.translation = Eigen::Vector3d(t[3 * f], t[3 * f + 1], t[3 * f + 2]);
      frame.gravity_in_cam = Eigen::Vector3d(gravity[3 * f], gravity[3 * f + 1], gravity[3 * f + 2]);
      LMB_CHECK(is_query[f] <= 1, name << ": /frames/is_query[" << f << "]: " << int(is_query[f]) << " is not 0 or 1");
      frame.is_query = is_query[f] != 0;
      frame.first_keypoint = first_keypoint[f];
      frame.num_keypoints = num_keypoints[f];
      map.frames.push_back(frame);
    }
    if (version == 1) assign_sessions_from_query_flags(&map);

    int64_t n = 0;
    const auto xy = r.column<float>("/keypoints/xy", -1, 2, 2, &n);
    const auto scale = r.column<float>("/keypoints/scale", n);
    const auto angle = r.column<float>("/keypoints/angle", n);
    map.descriptors = r.column<uint8_t>("/keypoints/descriptors", n, 2, descriptor_bytes);
    map.keypoint_landmark = r.column<int64_t>("/keypoints/landmark", n);
    map.keypoints.resize(n);
    for (int64_t k = 0; k < n; ++k) map.keypoints[k] = Keypoint{xy[2 * k], xy[2 * k + 1], scale[k], angle[k]};

    int64_t num_landmarks = 0;
    const auto position = r.column<double>("/landmarks/position", -1, 2, 3, &num_landmarks);
    const auto quality = r.column<float>("/landmarks/quality", num_landmarks);
    const auto reprojection = r.column<float>("/landmarks/mean_reprojection_error", num_landmarks);
    const auto map_obs = r.column<int32_t>("/landmarks/num_map_observations", num_landmarks);
    const auto query_obs = r.column<int32_t>("/landmarks/num_query_observations", num_landmarks);
    map.landmarks.resize(num_landmarks);
    for (int64_t l = 0; l < num_landmarks; ++l) {
      Landmark& lm = map.landmarks[l];
      lm.position = Eigen::Vector3d(position[3 * l], position[3 * l + 1], position[3 * l + 2]);
      lm.quality = quality[l];
      lm.mean_reprojection_error = reprojection[l];
      lm.num_map_observations = map_obs[l];
      lm.num_query_observations = query_obs[l];
    }
  } catch (const H5::Exception& e) {
    LMB_FAIL(name << ": cannot read HDF5 (truncated or damaged file?): " << e.getFuncName() << ": "
                  << e.getDetailMsg());
  }
  validate_landmark_map(map, name);
  return map;
}

}  // namespace lmb
