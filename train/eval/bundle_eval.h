// Localization with a bundle of area models (docs/areas.md) on a map's query frames, for
// `lboost localize --bundle` and `lboost eval --bundle`: each mode (a position prior of
// ground truth plus noise, no prior, and the single model for comparison) localizes every query
// frame at each RANSAC seed, single thread, one frame at a time, in one run.
//
// The prior of a query frame for noise M metres: its true camera centre moved M metres in a
// direction drawn from (prior_seed, frame id) (train/areas/area_split.h, prior_direction: the same
// draw as `lboost areas --prior-noise`), radius M. It never looks at anything else of the query.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "infer/bundle_localizer.h"
#include "infer/localizer.h"
#include "train/eval/metrics.h"

namespace lmb {

struct BundleEvalOptions {
  std::string bundle;               // bundle.txt
  std::string map;                  // map.h5 with the query frames
  std::string model;                // optional: the single model, localized on the same frames
  std::vector<double> prior_noise;  // one mode per value (metres, >= 0)
  bool no_prior = false;            // a mode scoring every area
  // Tracking modes, one per value (metres a frame, > 0): the query frames in name order (capture
  // order) through BundleLocalizer::track() with this tracking_radius; the first frame, and frames
  // the tracker loses, are localized in every area.
  std::vector<double> track;
  int tracking_areas = 2;  // BundleLocalizerOptions::tracking_areas
  // >= 0: tracking modes relocalize with a position prior of this noise (as prior_noise) instead of
  // in every area (BundleLocalizer::track's relocalization_prior).
  double track_prior_noise = -1.0;
  AreaSearch search = AreaSearch::kNearestFirst;  // how the areas a prior selects compete
  AreaWinner winner = AreaWinner::kSupport;       // which scored area's pose wins
  int area_threads = 1;                           // areas localized at once (BundleLocalizerOptions)
  uint64_t prior_seed = 1;                        // the prior's direction draw
  LocalizerOptions localizer;                     // pose.seed is the first RANSAC seed
  int seeds = 5;                                  // RANSAC seeds: localizer.pose.seed + 0 .. seeds - 1
  PoseThresholds thresholds;                      // a frame is correct within these
  BundleCacheLimits cache;                        // areas kept loaded (0 = no limit)
  bool memory_per_area = true;                    // load each area once alone first, measuring its resident memory
  // Throws lmb::Error naming the flag.
  void check() const;
};

struct BundleEvalResult {
  nlohmann::json report;  // docs/areas.md describes the fields
  std::string table;      // one line per mode
  // Each distinct error of an area that could not be loaded (the other areas were scored).
  std::vector<std::string> area_errors;
};

// Throws lmb::Error on invalid options, an unreadable bundle, map or model, a bundle or model of
// another map, no query frame, or when no area of the bundle could be loaded.
BundleEvalResult evaluate_bundle(const BundleEvalOptions& options);

}  // namespace lmb
