#include "train/cli/bundle_mode_options.h"

#include <map>
#include <string>
#include <vector>

#include "train/cli/cli_util.h"

namespace lmb::cli {

void add_bundle_mode_options(CLI::App* cmd, BundleEvalOptions* options) {
  // Every option below applies with --bundle only; the help lists them under their own heading.
  const size_t first = cmd->get_options().size();
  cmd->add_option("--prior-noise", options->prior_noise,
                  "A position prior per query frame, its true centre moved METRES in a seeded direction, "
                  "radius METRES (repeatable)");
  cmd->add_flag("--no-prior", options->no_prior, "Localize in every area, without a prior");
  cmd->add_option("--track", options->track,
                  "Track the query frames in capture order, the camera moving at most METRES a frame "
                  "(repeatable)");
  cmd->add_option("--track-prior-noise", options->track_prior_noise,
                  "--track: relocalize with a position prior of this noise (as --prior-noise) instead of "
                  "in every area (negative: every area)")
      ->capture_default_str();
  cmd->add_option("--tracking-areas", options->tracking_areas,
                  "--track: areas scored before the motion gate judges the winning pose")
      ->capture_default_str();
  cmd->add_flag_function(
      "--all-areas", [options](int64_t) { options->search = AreaSearch::kAll; },
      "With a prior, score every selected area (default: nearest area first, the first calibrated "
      "localized pose wins)");
  cmd->add_flag_function(
      "--winners-view", [options](int64_t) { options->search = AreaSearch::kWinnersView; },
      "With a prior, nearest area first, then the areas that see most of the current winning pose's "
      "view (fewer areas before the calibrated stop)");
  cmd->add_option("--area-winner", options->winner,
                  "Which scored area's pose wins: support (explains most keypoints with every scored "
                  "area's matches) or inliers (most inliers of its own area)")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, AreaWinner>{{"support", AreaWinner::kSupport}, {"inliers", AreaWinner::kInliers}}))
      ->default_str("support")
      ->option_text("support|inliers=support");
  cmd->add_option("--area-threads", options->area_threads,
                  "Areas of a frame localized at once, each on its own thread (the same result; "
                  "cpu_ms then counts the calling thread only: read wall_ms)")
      ->capture_default_str();
  add_seed_option(cmd, "--prior-seed", &options->prior_seed, "Seed of the prior's direction");
  cmd->add_option("--cache-areas", options->cache.max_areas,
                  "At most this many areas loaded (least recently used freed first; 0 = no limit)")
      ->capture_default_str();
  const std::vector<CLI::Option*> all = cmd->get_options();
  for (size_t i = first; i < all.size(); ++i) all[i]->group("With --bundle");
}

}  // namespace lmb::cli
