// Training one area (`lboost train --area FILE:ID`, docs/areas.md): the run's config records the
// area (TrainConfig::area), and whoever rebuilds its training set (train, export) resolves it to
// the area's landmarks, checking that the areas file still says what the run started with.
#pragma once

#include <string>
#include <vector>

#include "common/landmark_map.h"
#include "common/types.h"
#include "train/boost/train_config.h"

namespace lmb {

// From "FILE:ID": the file made absolute, the id, and the area's landmark count and hash read from
// the file. Throws lmb::Error naming `what` ("--area") or the file.
AreaReference make_area_reference(const std::string& file_colon_id, const std::string& what);

// The class landmarks of `area` on `map` (ascending). Throws lmb::Error naming the file when it
// cannot be read, was made from another map, or its area no longer has the recorded landmarks.
std::vector<landmark_t> area_class_landmarks(const AreaReference& area, const LandmarkMap& map);

}  // namespace lmb
