// The query frames of a map localized with one model, as `lboost localize --model` reports them:
// per frame the pose, its errors against the map's pose, timings and the matches; a summary of
// pose counts and errors, the accepted matches' metrics (train/eval/metrics.h, the definitions of
// `lboost eval`'s report) and mean timings.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/landmark_map.h"
#include "infer/localizer.h"
#include "infer/model.h"

namespace lmb {

struct MapLocalizationOptions {
  LocalizerOptions localizer;
  std::vector<std::string> queries;  // frame names; empty = every query frame
  int threads = 1;                   // frames localized in parallel (1..256)
  bool all_matches = false;          // every ranked match per frame, not only the pose's
};

// Localizes the frames; `is_class` per map landmark: a class of the model (check_model_fits_map).
// Each query session's selected frames are also tracked as one walk, in map order (WalkTracker,
// infer/walk_confidence.h): per frame "walk" says whether the walk reports its pose, and the
// summary's "walk" counts them; sequential after the frames are localized, so the same on any
// number of threads. Returns {"options", "frames", "summary", "calibration"}. Throws lmb::Error for an unknown frame
// name, a map without query frames, or threads outside 1..256.
nlohmann::json localize_map_frames(const std::shared_ptr<const Model>& model, const LandmarkMap& map,
                                   const std::vector<char>& is_class, const MapLocalizationOptions& options);

// A pose as poses.json writes it: {qw, qx, qy, qz, tx, ty, tz}, x_cam = R x_world + t.
nlohmann::json cam_from_world_json(const Rigid3d& cam_from_world);

// The summary as one line of text ("localize: N/M frames localized ...").
std::string map_localization_summary_line(const nlohmann::json& summary, int threads);

}  // namespace lmb
