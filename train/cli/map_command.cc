// lboost map: one or more collections (COLMAP sparse model + images, optional sessions.txt) -> map.h5.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "common/error.h"
#include "common/file_io.h"
#include "common/io/map_h5.h"
#include "common/io/session_file.h"
#include "train/cli/commands.h"
#include "train/mapping/map_gravity.h"
#include "train/mapping/map_report.h"
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
  std::string report;  // --report: JSON of the map's statistics and the mapping run
  std::string up = "+z";
  bool up_given = false;
  std::string refine_focal = "auto";  // --refine-focal: auto, on, off
  MapperOptions options;
};

// What the log adds to a focal check: whether the camera looks wrong, and what was done about it.
std::string focal_check_note(const MapperOptions& options, const FocalCheck& f) {
  if (std::abs(f.fitted_focal_px / f.focal_px - 1.0) <= options.auto_refine_min_change) return "";
  if (options.refine_focal == FocalRefinement::kAuto) return ": the intrinsics look wrong, refining them";
  return ": the intrinsics look wrong, try --refine-focal auto";
}

void print_pair_choice(const MapperOptions& options, const MapperStats& stats) {
  if (!stats.pairs_by_overlap) {
    std::printf("map: frame pairs by camera distance and viewing direction (%s)\n",
                options.pairs.max_center_distance > 0 ? "--pair-distance" : "no query frames to pair by view overlap");
    return;
  }
  const OverlapPairStats& o = stats.overlap;
  std::printf(
      "map: frame pairs: %lld among map frames by pose, giving a first map of %lld points; query frames: %lld pairs "
      "by pose and %lld by view overlap of that map (%.1f partners per query frame; query-partner distance median "
      "%.2f, 90th percentile %.2f, max %.2f world units); %d of %d query frames overlap no map frame\n",
      static_cast<long long>(stats.num_first_pass_pairs), static_cast<long long>(stats.num_first_pass_points),
      static_cast<long long>(stats.num_query_pose_pairs), static_cast<long long>(o.pairs), o.mean_partners,
      o.median_partner_distance, o.p90_partner_distance, o.max_partner_distance, o.query_frames_without,
      o.query_frames_with + o.query_frames_without);
}

// What the run did and made: frames, sessions, pairs, landmarks, errors, the focal check or
// refinement, times.
void print_map_summary(const LandmarkMap& map, const MapperOptions& options, const MapperStats& stats,
                       const std::string& out) {
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
  print_pair_choice(options, stats);
  std::printf("map: %lld frame pairs, %lld matches, %lld tracks -> %lld landmarks\n",
              static_cast<long long>(stats.num_pairs), static_cast<long long>(stats.num_matches),
              static_cast<long long>(stats.num_tracks), static_cast<long long>(stats.num_landmarks));
  std::printf(
      "map: %.2f map observations per landmark, %lld query keypoints with a landmark, "
      "mean reprojection error %.2f px\n",
      stats.mean_map_observations, static_cast<long long>(stats.num_query_observations),
      stats.mean_reprojection_error_px);
  const nlohmann::json per_frame = frame_reprojection_summary(map);
  std::printf("map: %s\n", frame_reprojection_text(per_frame).c_str());
  for (size_t c = 0; c < stats.focal_check.size(); ++c) {
    const FocalCheck& f = stats.focal_check[c];
    std::printf(
        "map: focal check, camera %zu: a refinement step on the map's tracks (%lld observations, poses fixed) moves "
        "the focal length %.2f -> %.2f px (%+.2f%%), their mean reprojection error %.2f -> %.2f px%s\n",
        c, static_cast<long long>(f.observations), f.focal_px, f.fitted_focal_px,
        100.0 * (f.fitted_focal_px / f.focal_px - 1.0), f.error_before_px, f.error_after_px,
        focal_check_note(options, f).c_str());
  }
  if (stats.refined) {
    std::istringstream lines(camera_refinement_text(stats));
    for (std::string line; std::getline(lines, line);) std::printf("map: camera refinement: %s\n", line.c_str());
  }
  std::printf("map: %.1f s (detect %.1f s, match %.1f s, triangulate %.1f s, %s %.1f s), wrote %s\n",
              stats.total_seconds, stats.detect_seconds, stats.match_seconds, stats.triangulate_seconds,
              stats.refined ? "refine" : "focal check", stats.refine_seconds, out.c_str());
}

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
  check_outputs_not_inputs({{args.out, "--out"}, {args.report, "--report"}}, read);
  check_writable_file(args.out, "--out");  // before the gravity choice and the mapping run
  if (!args.report.empty()) {
    LMB_CHECK(!same_file(args.report, args.out), "--report " << args.report << " is the --out map file");
    check_writable_file(args.report, "--report");
  }
  MapperOptions options = args.options;
  options.refine_focal = parse_focal_refinement(args.refine_focal);
  LMB_CHECK(!options.refinement.principal_point || options.refine_focal != FocalRefinement::kOff,
            "--refine-principal-point needs --refine-focal auto or on");
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
  print_map_summary(map, options, stats, args.out);
  if (!args.report.empty()) {
    nlohmann::json report = map_statistics(map);
    report["mapping"] = mapper_statistics(stats);
    write_file_atomically(args.report, report.dump(2) + "\n");
    std::printf("map: wrote %s\n", args.report.c_str());
  }
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
  cmd->add_option("--report", args->report,
                  "Also write a JSON report: the map's statistics (lboost inspect --json without the Hamming figure) "
                  "and the mapping run (frame pairs, matches, times, camera refinement)");
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
                  "Pair frames by camera centre distance (at most this, world units) and viewing direction alone; 0 = "
                  "that rule at an automatic distance (8 x the map frames' median spacing), and each query frame also "
                  "paired with the map frames that see most of its scene (--pairs-per-frame)")
      ->capture_default_str();
  cmd->add_option("--pairs-per-frame", args->options.overlap.partners_per_frame,
                  "Without --pair-distance: map frames each query frame is paired with by view overlap (those that see "
                  "most of the points of a first map it sees, spread out in viewpoint)")
      ->capture_default_str();
  cmd->add_option("--refine-focal", args->refine_focal,
                  "Refine each camera's focal length on the map's own tracks (poses fixed), then match and "
                  "triangulate again with it; the map stores the refined camera. auto: when a first refinement "
                  "step (the focal check, always logged) moves it by more than 1%; on: always; off: log the check "
                  "only")
      ->check(CLI::IsMember({"auto", "on", "off"}))
      ->capture_default_str();
  cmd->add_flag("--refine-principal-point", args->options.refinement.principal_point,
                "When the focal length is refined: refine the principal point too");
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
