// lboost map: collection (COLMAP sparse text model + images) -> map.h5.
#include <cstdio>
#include <string>

#include <spdlog/spdlog.h>

#include "common/error.h"
#include "common/file_io.h"
#include "common/io/map_h5.h"
#include "train/cli/commands.h"
#include "train/mapping/map_gravity.h"
#include "train/mapping/mapper.h"

namespace lmb::cli {

namespace {

struct MapArgs {
  std::string collection;
  std::string out;
  std::string up = "+z";
  std::string gravity;  // --gravity: a file, "none", or "" (COLLECTION/gravity.txt when present)
  bool up_given = false;
  MapperOptions options;
};

void run_map(const MapArgs& args) {
  MapperOptions options = args.options;
  MapGravityRequest request;
  request.collection = args.collection;
  request.gravity = args.gravity;
  request.up = args.up;
  request.up_given = args.up_given;
  const MapGravityChoice gravity = choose_map_gravity(request);
  options.up = gravity.up;
  options.gravity_file = gravity.gravity_file;
  options.check();
  check_writable_file(args.out, "--out");  // before the mapping run, not after it
  spdlog::info("map: collection {} -> {}", args.collection, args.out);
  std::printf("map: gravity: %s\n", gravity.description.c_str());
  std::fflush(stdout);
  MapperStats stats;
  const LandmarkMap map = map_collection(args.collection, options, &stats);
  LMB_CHECK(!map.landmarks.empty(), args.collection << ": no landmark survived mapping (too few overlapping "
                                                    << "map frames?); nothing written");
  write_map_h5(map, args.out);
  std::printf("map: %d map frames, %d query frames, %lld keypoints (%s, %d bytes)\n", stats.num_map_frames,
              stats.num_query_frames, static_cast<long long>(stats.num_keypoints), map.detector.c_str(),
              map.descriptor_bytes);
  std::printf("map: %lld frame pairs, %lld matches, %lld tracks -> %lld landmarks\n",
              static_cast<long long>(stats.num_pairs), static_cast<long long>(stats.num_matches),
              static_cast<long long>(stats.num_tracks), static_cast<long long>(stats.num_landmarks));
  std::printf("map: %.2f map observations per landmark, %lld query keypoints with a landmark, "
              "mean reprojection error %.2f px\n",
              stats.mean_map_observations, static_cast<long long>(stats.num_query_observations),
              stats.mean_reprojection_error_px);
  std::printf("map: %.1f s (detect %.1f s, match %.1f s, triangulate %.1f s), wrote %s\n", stats.total_seconds,
              stats.detect_seconds, stats.match_seconds, stats.triangulate_seconds, args.out.c_str());
}

}  // namespace

void add_map_command(CLI::App& app) {
  auto args = std::make_shared<MapArgs>();
  auto* cmd = app.add_subcommand("map", "Build a landmark map (map.h5) from a collection of posed images");
  cmd->add_option("--collection", args->collection,
                  "Collection folder: sparse/{cameras,images,points3D}.txt and images/<name>")
      ->required();
  cmd->add_option("--out", args->out, "Output map file (HDF5), written atomically")->required();
  cmd->add_option("--query-prefix", args->options.query_prefix,
                  "Images whose name starts with this are query frames (held out of training)")
      ->capture_default_str();
  cmd->add_option("--detector", args->options.detector.detector, "Binary keypoint detector")
      ->check(CLI::IsMember({"BRISK", "ORB"}))
      ->capture_default_str();
  cmd->add_option("--max-keypoints", args->options.detector.max_keypoints, "Keypoints per image (strongest)")
      ->capture_default_str();
  cmd->add_option("--gravity", args->gravity,
                  "Per-image gravity file (IMAGE_NAME gx gy gz: down, camera frame), or 'none' for --up. "
                  "Default: COLLECTION/gravity.txt when it exists, else --up");
  auto* up = cmd->add_option("--up", args->up,
                             "World up axis: +x, -x, +y, -y, +z, -z (gravity is -up); with "
                             "COLLECTION/gravity.txt present it must agree with the file")
                 ->capture_default_str();
  cmd->add_option("--threads", args->options.threads, "Worker threads")->capture_default_str();
  cmd->add_option("--pair-distance", args->options.pairs.max_center_distance,
                  "Max camera centre distance of matched frame pairs, world units (0 = automatic)")
      ->capture_default_str();
  cmd->add_option("--max-depth", args->options.matching.max_depth, "Max depth for guided matching, world units")
      ->capture_default_str();
  cmd->add_option("--min-observations", args->options.min_map_observations,
                  "Map-frame observations a landmark needs")
      ->capture_default_str();
  cmd->callback([args, up] {
    args->up_given = up->count() > 0;
    run_map(*args);
  });
}

}  // namespace lmb::cli
