#include "train/world/world_writer.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <system_error>

#include <unistd.h>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/error.h"
#include "common/file_io.h"
#include "common/io/colmap_model.h"
#include "common/io/session_file.h"
#include "train/world/renderer.h"
#include "train/world/trajectory.h"

namespace fs = std::filesystem;

namespace lmb {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Encoded in memory, then written by the project's atomic writer (errors name the file and the
// system's reason; cv::imwrite does not check the final flush).
void write_png(const fs::path& path, const cv::Mat& image) {
  std::vector<uint8_t> png;
  bool ok = false;
  try {
    ok = cv::imencode(".png", image, png, {cv::IMWRITE_PNG_COMPRESSION, 3});
  } catch (const cv::Exception& e) {
    LMB_FAIL(path.string() << ": cannot encode image: " << e.what());
  }
  LMB_CHECK(ok, path.string() << ": cannot encode image");
  write_file_atomically(path, png.data(), png.size());
}

nlohmann::json lighting_json(const Lighting& l) {
  return {{"ambient", l.ambient},       {"lamp_power", l.lamp_power},  {"lamp_range_m", l.lamp_range_m},
          {"lamp_scale", l.lamp_scale}, {"emissive", l.emissive},      {"gain", l.gain},
          {"exponent", l.exponent},     {"noise_sigma", l.noise_sigma}};
}

// Prepares the output: checks that out_dir may be replaced and creates the temporary folder.
fs::path make_temp_dir(const fs::path& out_dir) {
  std::error_code ec;
  if (fs::exists(out_dir, ec)) {
    LMB_CHECK(fs::is_directory(out_dir, ec), out_dir.string() << ": exists and is not a folder");
    LMB_CHECK(fs::is_empty(out_dir, ec) || fs::exists(out_dir / "world.json", ec),
              out_dir.string() << ": exists and is neither empty nor a world folder (no world.json); "
                                  "refusing to overwrite it");
  }
  fs::path parent = out_dir.parent_path();
  if (parent.empty()) parent = ".";
  fs::create_directories(parent, ec);
  LMB_CHECK(!ec && fs::is_directory(parent), parent.string() << ": cannot create output folder: " << ec.message());
  const fs::path tmp = parent / ("." + out_dir.filename().string() + ".tmp-" + std::to_string(::getpid()));
  fs::remove_all(tmp, ec);
  fs::create_directories(tmp / "sparse", ec);
  LMB_CHECK(!ec, tmp.string() << ": cannot create output folder: " << ec.message());
  // Probe writability (create_directories can succeed on some read-only mounts as root).
  try {
    check_writable_folder(tmp, "output folder");
  } catch (const Error& e) {
    fs::remove_all(tmp, ec);
    LMB_FAIL(out_dir.string() << ": output folder is not writable (" << e.what() << ")");
  }
  return tmp;
}

void commit_dir(const fs::path& tmp, const fs::path& out_dir) {
  std::error_code ec;
  fs::path old;
  if (fs::exists(out_dir, ec)) {
    old = tmp.string() + ".old";
    fs::remove_all(old, ec);
    fs::rename(out_dir, old, ec);
    LMB_CHECK(!ec, out_dir.string() << ": cannot replace the existing folder: " << ec.message());
  }
  fs::rename(tmp, out_dir, ec);
  LMB_CHECK(!ec, out_dir.string() << ": cannot move the finished world into place: " << ec.message());
  if (!old.empty()) fs::remove_all(old, ec);
}

// world.json: what the world holds (counts, camera, geometry, layout, sessions and their passes
// and lighting) and the image formats.
nlohmann::json world_json(const WorldOptions& options, const World& world, const Camera& camera,
                          const std::vector<Session>& sessions, const WorldWriteStats& stats) {
  const WorldSummary& s = world.summary;
  nlohmann::json j;
  j["format"] = "lmb-world";
  j["format_version"] = 1;
  j["preset"] = options.preset;
  j["seed"] = options.seed;
  j["non_aliased"] = options.non_aliased;
  j["units"] = "m";
  j["up_axis"] = {0, 0, 1};
  j["gravity"] = {0, 0, -1};
  j["counts"] = {{"map_frames", stats.map_frames},
                 {"query_frames", stats.query_frames},
                 {"map_sessions", options.map_sessions},
                 {"query_sessions", options.query_sessions},
                 {"doors", s.doors},
                 {"posters", s.posters},
                 {"poster_textures", s.poster_textures},
                 {"pillars", s.pillars},
                 {"room_plates", s.plates},
                 {"signs", s.signs},
                 {"stains", s.stains},
                 {"objects", s.objects},
                 {"lamps", s.lamps},
                 {"floor_tiles", s.floor_tiles},
                 {"ceiling_panels", s.ceiling_panels},
                 {"textures", s.textures}};
  if (stats.outside_frames > 0) {
    // Frames of the outside corridor: kOutsideOffsetY metres along +y, never seen by a map session.
    j["counts"]["outside_frames"] = stats.outside_frames;
    j["outside"] = {{"kind", "a second corridor of the same building, same repeated textures, own layout"},
                    {"offset_m", {0.0, kOutsideOffsetY, 0.0}},
                    {"y_range", {kOutsideOffsetY - world.width / 2, kOutsideOffsetY + world.width / 2}}};
  }
  j["camera"] = {{"camera_id", 1},
                 {"model", camera_model_name(camera.model)},
                 {"width", camera.width},
                 {"height", camera.height},
                 {"params", camera.params}};
  j["geometry"] = {{"kind", "straight corridor"},
                   {"length_m", world.length},
                   {"width_m", world.width},
                   {"height_m", world.height},
                   {"x_range", {0.0, world.length}},
                   {"y_range", {-world.width / 2, world.width / 2}},
                   {"z_range", {0.0, world.height}},
                   {"floor_tile_m", world.tile_size},
                   {"ceiling_panel_m", world.panel_size},
                   {"lamp_spacing_m", world.lamp_spacing},
                   {"pillar_bay_m", options.pillar_bay_m},
                   {"boxes", world.boxes.size()}};
  j["layout"] = {{"poster_designs", options.poster_designs},       {"door_share", options.door_share},
                 {"poster_share", options.poster_share},           {"sign_share", options.sign_share},
                 {"wall_stains_per_m", options.wall_stains_per_m}, {"floor_stains_per_m", options.floor_stains_per_m}};
  for (const Session& session : sessions) {
    nlohmann::json passes = nlohmann::json::array();
    for (const PassParams& p : session.passes) {
      passes.push_back({{"heading_deg", p.heading * 180.0 / M_PI},
                        {"lateral_offset_m", p.lateral_m},
                        {"camera_height_m", p.height_m},
                        {"yaw_amplitude_deg", p.yaw_amplitude_deg},
                        {"yaw_period_m", p.yaw_period_m},
                        {"pitch_mean_deg", p.pitch_mean_deg},
                        {"pitch_amplitude_deg", p.pitch_amplitude_deg},
                        {"roll_amplitude_deg", p.roll_amplitude_deg}});
    }
    j["sessions"][session.name] = {
        {"kind", session_kind_name(session.kind)},    {"frames", session.cam_from_world.size()},
        {"image_dir", "images/" + session.name},      {"depth_dir", "depth/" + session.name},
        {"time_of_day", session.time_of_day},         {"passes", passes},
        {"lighting", lighting_json(session.lighting)}};
  }
  j["images"] = {{"format", "png"}, {"channels", 1}, {"bit_depth", 8}};
  j["depth"] = {
      {"format", "png"}, {"bit_depth", 16}, {"kind", "z-depth of the pixel centre"}, {"units", "mm"}, {"invalid", 0}};
  return j;
}

}  // namespace

WorldWriteStats write_world(const WorldOptions& options, const fs::path& out_dir,
                            const std::function<void(int, int)>& progress) {
  options.check();
  LMB_CHECK(!out_dir.empty(), "world: --out is required");
  const fs::path tmp = make_temp_dir(out_dir);
  try {
    WorldWriteStats stats;
    const auto t0 = std::chrono::steady_clock::now();
    const World world = build_world(options);
    const Camera camera = world_camera(options.image_scale);
    const RayTable rays(camera, options.supersampling);
    std::vector<Session> sessions = make_world_sessions(world);
    // The outside corridor and its session (WorldOptions::outside_frames).
    World outside_world;
    if (options.outside_frames > 0) {
      WorldOptions oo = options;
      oo.region = 1;
      outside_world = build_world(oo);
      sessions.push_back(make_outside_session(outside_world, options.outside_frames));
    }
    stats.build_seconds = seconds_since(t0);
    stats.summary = world.summary;

    const auto t1 = std::chrono::steady_clock::now();
    ColmapModel model;
    model.cameras[1] = camera;
    std::vector<MapSession> session_list;
    int total = 0;
    for (const Session& session : sessions) {
      total += static_cast<int>(session.cam_from_world.size());
      (session.kind == SessionKind::kMap     ? stats.map_frames
       : session.kind == SessionKind::kQuery ? stats.query_frames
                                             : stats.outside_frames) += static_cast<int>(session.cam_from_world.size());
      session_list.push_back(MapSession{session.name, session.kind});
      for (const char* sub : {"images", "depth"}) {
        std::error_code ec;
        fs::create_directories(tmp / sub / session.name, ec);
        LMB_CHECK(!ec, tmp.string() << ": cannot create output folder: " << ec.message());
      }
    }
    write_session_file(session_list, tmp / kSessionFileName);
    int done = 0;
    for (const Session& session : sessions) {
      for (size_t i = 0; i < session.cam_from_world.size(); ++i) {
        char name[64];
        std::snprintf(name, sizeof(name), "%s/%06zu.png", session.name.c_str(), i);
        const World& scene = session.kind == SessionKind::kOutside ? outside_world : world;
        const RenderedFrame frame = render_frame(scene, rays, session.cam_from_world[i], session.lighting,
                                                 session.frame_key_base | i, options.threads);
        write_png(tmp / "images" / name, frame.image);
        write_png(tmp / "depth" / name, frame.depth_mm);
        ColmapImage im;
        im.image_id = static_cast<int>(model.images.size()) + 1;
        im.camera_id = 1;
        im.name = name;
        im.cam_from_world = session.recorded_cam_from_world(i);
        model.images.push_back(im);
        ++done;
        if (progress) progress(done, total);
      }
    }
    write_colmap_text(model, tmp / "sparse");

    write_file_atomically(tmp / "world.json", world_json(options, world, camera, sessions, stats).dump(2) + "\n");
    stats.render_seconds = seconds_since(t1);
    commit_dir(tmp, out_dir);
    return stats;
  } catch (...) {
    std::error_code ec;
    fs::remove_all(tmp, ec);
    throw;
  }
}

}  // namespace lmb
