// lboost map: one or more collections (COLMAP sparse model + images, optional sessions.txt) -> map.h5.
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "common/error.h"
#include "common/file_io.h"
#include "common/io/map_h5.h"
#include "common/io/session_file.h"
#include "train/cli/commands.h"
#include "train/mapping/map_gravity.h"
#include "train/mapping/mapper.h"

namespace lmb::cli {

namespace {

struct MapArgs {
  std::vector<std::string> collections;
  std::vector<std::string> labels;
  // --gravity: none (each collection's gravity.txt when present, else --up) or one per collection,
  // each a file or "none"
  std::vector<std::string> gravity;
  std::string out;
  std::string up = "+z";
  bool up_given = false;
  MapperOptions options;
};

void run_map(const MapArgs& args) {
  // What mapping reads of each collection: its sparse model, images, sessions.txt and gravity file.
  std::vector<NamedPath> read;
  for (const std::string& c : args.collections) {
    const std::filesystem::path collection(c);
    read.push_back({collection / "sparse", "--collection", true});
    read.push_back({collection / "images", "--collection", true});
    read.push_back({collection / kSessionFileName, "--collection"});
    read.push_back({collection / "gravity.txt", "--collection"});
  }
  for (const std::string& g : args.gravity) {
    if (g != "none") read.push_back({g, "--gravity"});
  }
  check_outputs_not_inputs({{args.out, "--out"}}, read);
  check_writable_file(args.out, "--out");  // before the gravity choice and the mapping run
  MapperOptions options = args.options;
  const size_t n = args.collections.size();
  LMB_CHECK(args.labels.empty() || args.labels.size() == n,
            "--label: " << args.labels.size() << " labels for " << n << " collections (give one per --collection)");
  LMB_CHECK(args.gravity.empty() || args.gravity.size() == n,
            "--gravity: " << args.gravity.size() << " values for " << n
                          << " collections (give one per --collection, in the same order: a file or 'none')");
  std::vector<CollectionInput> inputs;
  std::string names;
  for (size_t k = 0; k < n; ++k) {
    MapGravityRequest request;
    request.collection = args.collections[k];
    request.gravity = args.gravity.empty() ? "" : args.gravity[k];
    request.up = args.up;
    request.up_given = args.up_given;
    const MapGravityChoice gravity = choose_map_gravity(request);
    options.up = gravity.up;  // --up's axis, the same for every collection
    if (n == 1) {
      std::printf("map: gravity: %s\n", gravity.description.c_str());
    } else {
      std::printf("map: gravity of %s: %s\n", args.collections[k].c_str(), gravity.description.c_str());
    }
    inputs.push_back(
        CollectionInput{args.collections[k], args.labels.empty() ? "" : args.labels[k], gravity.gravity_file});
    names += (k ? ", " : "") + args.collections[k];
  }
  options.check();
  spdlog::info("map: collection{} {} -> {}", n > 1 ? "s" : "", names, args.out);
  std::fflush(stdout);
  MapperStats stats;
  const LandmarkMap map = map_collections(inputs, options, &stats);
  LMB_CHECK(!map.landmarks.empty(), names << ": no landmark survived mapping (too few overlapping "
                                          << "map frames?); nothing written");
  write_map_h5(map, args.out);
  std::printf("map: %d map frames, %d query frames (%d outside), %lld keypoints (%s, %d bytes)\n", stats.num_map_frames,
              stats.num_query_frames, stats.num_outside_frames, static_cast<long long>(stats.num_keypoints),
              map.detector.c_str(), map.descriptor_bytes);
  std::vector<int> frames(map.sessions.size(), 0);
  for (const MapFrame& f : map.frames) ++frames[static_cast<size_t>(f.session)];
  std::string session_list;
  for (size_t s = 0; s < map.sessions.size(); ++s) {
    session_list += (s ? ", " : "") + map.sessions[s].name + " (" + session_kind_name(map.sessions[s].kind) + ", " +
                    std::to_string(frames[s]) + " frames)";
  }
  std::printf("map: %zu sessions: %s\n", map.sessions.size(), session_list.c_str());
  std::printf("map: %lld frame pairs, %lld matches, %lld tracks -> %lld landmarks\n",
              static_cast<long long>(stats.num_pairs), static_cast<long long>(stats.num_matches),
              static_cast<long long>(stats.num_tracks), static_cast<long long>(stats.num_landmarks));
  std::printf(
      "map: %.2f map observations per landmark, %lld query keypoints with a landmark, "
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
  cmd->add_option("--collection", args->collections,
                  "Collection folder: sparse/{cameras,images,points3D}.txt, images/<name>, optional sessions.txt; "
                  "repeat it to join several collections (poses in one world frame) into one map")
      ->required()
      ->take_all();
  cmd->add_option("--label", args->labels,
                  "With several collections: one label per collection, prefixed to its frame and session names "
                  "(LABEL/NAME; default: the collection's folder name)")
      ->delimiter(',');
  cmd->add_option("--out", args->out, "Output map file (HDF5), written atomically")->required();
  cmd->add_option("--query-prefix", args->options.query_prefix,
                  "For a collection without sessions.txt: images whose name starts with this are the query "
                  "session 'query' (held out of training), the others the map session 'map'")
      ->capture_default_str();
  cmd->add_option("--detector", args->options.detector.detector, "Binary keypoint detector")
      ->check(CLI::IsMember({"BRISK", "ORB"}))
      ->capture_default_str();
  cmd->add_option("--max-keypoints", args->options.detector.max_keypoints, "Keypoints per image (strongest)")
      ->capture_default_str();
  cmd->add_option("--gravity", args->gravity,
                  "Per-image gravity file (IMAGE_NAME gx gy gz: down, camera frame), or 'none' for --up; with "
                  "several collections one per collection, in order. Default: each COLLECTION/gravity.txt when "
                  "it exists, else --up");
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
  cmd->add_option("--min-observations", args->options.min_map_observations, "Map-frame observations a landmark needs")
      ->capture_default_str();
  cmd->callback([args, up] {
    args->up_given = up->count() > 0;
    run_map(*args);
  });
}

}  // namespace lmb::cli
