// `lboost world`: renders the self-similar corridor world into a collection (see
// train/world/world_writer.h for the folder layout).
#include <cstdio>

#include <spdlog/spdlog.h>

#include "common/error.h"
#include "train/cli/commands.h"
#include "train/world/landmark_stats.h"
#include "train/world/world_writer.h"

namespace lmb::cli {

namespace {

struct WorldArgs {
  std::string preset = "default";
  uint64_t seed = 1;
  std::string out;
  bool non_aliased = false;
  bool stats = false;
  int map_frames = -1;
  int query_frames = -1;
  int outside_frames = -1;
  int map_sessions = -1;
  int query_sessions = -1;
  double length_m = -1.0;
  int threads = 2;
  // Layout overrides (-1: the preset's value).
  int poster_designs = -1;
  double image_scale = -1.0;
  double pillar_bay_m = -1.0, door_share = -1.0, poster_share = -1.0, sign_share = -1.0;
  double wall_stains_per_m = -1.0, floor_stains_per_m = -1.0;
};

void override_if_set(double value, double* field) {
  if (value != -1.0) *field = value;
}

void run_world(const WorldArgs& a) {
  WorldOptions o = world_preset(a.preset);
  o.seed = a.seed;
  o.non_aliased = a.non_aliased;
  o.threads = a.threads;
  if (a.map_frames != -1) o.map_frames = a.map_frames;
  if (a.query_frames != -1) o.query_frames = a.query_frames;
  if (a.outside_frames != -1) o.outside_frames = a.outside_frames;
  if (a.map_sessions != -1) o.map_sessions = a.map_sessions;
  if (a.query_sessions != -1) o.query_sessions = a.query_sessions;
  if (a.length_m != -1.0) o.length_m = a.length_m;
  if (a.poster_designs != -1) o.poster_designs = a.poster_designs;
  override_if_set(a.image_scale, &o.image_scale);
  override_if_set(a.pillar_bay_m, &o.pillar_bay_m);
  override_if_set(a.door_share, &o.door_share);
  override_if_set(a.poster_share, &o.poster_share);
  override_if_set(a.sign_share, &o.sign_share);
  override_if_set(a.wall_stains_per_m, &o.wall_stains_per_m);
  override_if_set(a.floor_stains_per_m, &o.floor_stains_per_m);
  o.check();
  LMB_CHECK(!a.out.empty(), "world: --out is required");
  spdlog::info(
      "world: preset {} seed {} {} corridor {:.1f} m, {} map frames in {} session{} + {} query frames in "
      "each of {} session{} -> {}",
      o.preset, o.seed, o.non_aliased ? "non-aliased" : "aliased", o.length_m, o.map_frames, o.map_sessions,
      o.map_sessions > 1 ? "s" : "", o.query_frames, o.query_sessions, o.query_sessions > 1 ? "s" : "", a.out);
  int last_decile = 0;
  const WorldWriteStats s = write_world(o, a.out, [&](int done, int total) {
    const int decile = done * 10 / total;
    if (decile > last_decile) {
      last_decile = decile;
      spdlog::info("world: {}/{} frames", done, total);
    }
  });
  spdlog::info("world: built in {:.2f} s, rendered and wrote {} + {} frames in {:.1f} s ({:.3f} s/frame)",
               s.build_seconds, s.map_frames, s.query_frames, s.render_seconds,
               s.render_seconds / std::max(1, s.map_frames + s.query_frames + s.outside_frames));
  if (a.stats) {
    const LandmarkStats ls = estimate_landmarks(a.out);
    std::printf(
        "landmark estimate (BRISK, exact depth, 1 cm merge radius): map_frames %d, map_keypoints %lld (%.0f/frame), "
        "points %lld, "
        "landmarks>=3 %lld, landmarks>=10 %lld, query_keypoints %lld, query_on_landmark %lld (%.1f%%), %.1f s\n",
        ls.map_frames, static_cast<long long>(ls.map_keypoints),
        ls.map_keypoints / std::max(1.0, static_cast<double>(ls.map_frames)), static_cast<long long>(ls.points),
        static_cast<long long>(ls.landmarks_3), static_cast<long long>(ls.landmarks_10),
        static_cast<long long>(ls.query_keypoints), static_cast<long long>(ls.query_on_landmark),
        100.0 * ls.query_on_landmark / std::max<int64_t>(1, ls.query_keypoints), ls.seconds);
  }
}

}  // namespace

void add_world_command(CLI::App& app) {
  auto args = std::make_shared<WorldArgs>();
  auto* cmd = app.add_subcommand(
      "world",
      "Render a self-similar indoor corridor world (map and query sessions) into a COLMAP collection with depth");
  cmd->add_option("--preset", args->preset, "tiny | default | paper")->capture_default_str();
  add_seed_option(cmd, "--seed", &args->seed, "World seed (layout, textures, trajectories, noise)");
  cmd->add_option("--out", args->out, "Output folder (replaced atomically)")->required();
  cmd->add_flag("--non-aliased", args->non_aliased,
                "Control world: every element instance gets a unique texture (same geometry and trajectories)");
  cmd->add_option("--map-frames", args->map_frames,
                  "Override the preset's map frame count (all map sessions together, split evenly)");
  cmd->add_option("--query-frames", args->query_frames, "Override the preset's frame count of each query session");
  cmd->add_option("--outside-frames", args->outside_frames,
                  "Frames of an 'outside' session rendered in a second corridor of the same building that no map "
                  "session sees (0 = none; default: the preset's)");
  cmd->add_option("--map-sessions", args->map_sessions,
                  "Override the preset's map sessions (1-4): other lanes, camera heights, yaw patterns and lighting");
  cmd->add_option("--query-sessions", args->query_sessions,
                  "Override the preset's query sessions (1-3), each unlike every map session");
  cmd->add_option("--length", args->length_m, "Override the preset's corridor length (m)");
  cmd->add_option("--threads", args->threads, "Render threads")->capture_default_str();
  cmd->add_option("--image-scale", args->image_scale, "Override: image size relative to 640 x 480");
  cmd->add_option("--poster-designs", args->poster_designs, "Override: distinct poster designs (aliased world)");
  cmd->add_option("--pillar-bay", args->pillar_bay_m, "Override: pillar spacing (m)");
  cmd->add_option("--door-share", args->door_share, "Override: share of wall slots with a door");
  cmd->add_option("--poster-share", args->poster_share, "Override: share of wall slots with a poster");
  cmd->add_option("--sign-share", args->sign_share, "Override: share of wall slots with a unique sign");
  cmd->add_option("--wall-stains", args->wall_stains_per_m, "Override: unique stains per metre of each side wall");
  cmd->add_option("--floor-stains", args->floor_stains_per_m, "Override: unique floor stains per metre");
  cmd->add_flag("--stats", args->stats,
                "After rendering, estimate landmark counts (BRISK + exact depth, voxel hashing)");
  cmd->callback([args] { run_world(*args); });
}

}  // namespace lmb::cli
