// lboost inspect: statistics of a map.h5, including the descriptor aliasing figure (plain exact
// Hamming nearest neighbour precision@1 of query keypoints against the map's keypoints); given a
// training checkpoint (RUN/checkpoints/ckpt-*.h5), reads it whole, CRC included, and prints its
// rounds, rank count and data source (exit 1 with the reader's message if it is torn or corrupt).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "common/error.h"
#include "common/io/map_h5.h"
#include "train/checkpoint/checkpoint_h5.h"
#include "train/cli/commands.h"
#include "train/mapping/map_report.h"

namespace lmb::cli {

namespace {

struct InspectArgs {
  std::string map_path;
  bool json = false;
  bool no_nn = false;
  int threads = 2;
  std::string depth_collection;  // rendered world folder with depth/ for the ground-truth check
};

void inspect_checkpoint(const InspectArgs& args) {
  const Checkpoint ck = read_checkpoint(args.map_path);
  const nlohmann::json j = {{"file", args.map_path},
                            {"format", kCheckpointFormat},
                            {"rounds", ck.rounds},
                            {"ranks", ck.ranks},
                            {"data", ck.data},
                            {"crc32", "ok"},
                            {"stumps", ck.state.model.stumps.size()}};
  if (args.json) {
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf("%s: training checkpoint, %d rounds, written by %d rank(s), data %s; complete, CRC-32 ok\n",
              args.map_path.c_str(), ck.rounds, ck.ranks, ck.data.c_str());
}

void run_inspect(const InspectArgs& args) {
  LMB_CHECK(args.threads >= 1 && args.threads <= 256, "inspect: --threads = " << args.threads << " must be in 1..256");
  if (std::filesystem::path(args.map_path).filename().string().rfind("ckpt-", 0) == 0) {
    inspect_checkpoint(args);
    return;
  }
  const LandmarkMap map = read_map_h5(args.map_path);
  MapReportOptions o;
  o.hamming_nn = !args.no_nn;
  o.threads = args.threads;
  o.depth_collection = args.depth_collection;
  nlohmann::json j = map_report(map, o);
  j["file"] = args.map_path;
  if (args.json) {
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf("%s: %s", args.map_path.c_str(), map_report_text(j).c_str());
}

}  // namespace

void add_inspect_command(CLI::App& app) {
  auto args = std::make_shared<InspectArgs>();
  auto* cmd = app.add_subcommand(
      "inspect", "Print statistics of a map.h5 and its descriptor aliasing figure, or check a checkpoint");
  cmd->add_option("map", args->map_path, "map.h5 file, or a training checkpoint ckpt-*.h5")->required();
  cmd->add_flag("--json", args->json, "Print JSON instead of text");
  cmd->add_flag("--no-nn", args->no_nn, "Skip the Hamming nearest-neighbour figure");
  cmd->add_option("--depth-check", args->depth_collection,
                  "Rendered world folder: check landmarks against its depth maps (purity, position error)");
  cmd->add_option("--threads", args->threads, "Threads for the nearest-neighbour search")->capture_default_str();
  cmd->callback([args] { run_inspect(*args); });
}

}  // namespace lmb::cli
