#include "train/areas/area_training.h"

#include <cinttypes>
#include <cstdio>
#include <filesystem>

#include "common/error.h"
#include "train/areas/area_file.h"

namespace lmb {

AreaReference make_area_reference(const std::string& file_colon_id, const std::string& what) {
  AreaReference area;
  parse_area_reference(file_colon_id, what, &area.file, &area.id);
  area.file = std::filesystem::absolute(area.file).lexically_normal().string();
  const AreaFile file = read_area_file(area.file);
  LMB_CHECK(static_cast<size_t>(area.id) < file.split.areas.size(),
            what << " " << file_colon_id << ": " << area.file << " has no area " << area.id << " (it has "
                 << file.split.areas.size() << ", ids 0.." << file.split.areas.size() - 1 << ")");
  const std::vector<landmark_t>& landmarks = file.split.areas[static_cast<size_t>(area.id)].landmarks;
  area.landmarks = static_cast<int64_t>(landmarks.size());
  area.landmarks_hash = landmark_list_hash(landmarks);
  return area;
}

std::vector<landmark_t> area_class_landmarks(const AreaReference& area, const LandmarkMap& map) {
  std::vector<landmark_t> landmarks = read_area_landmarks(area.file, area.id, map);
  const uint64_t hash = landmark_list_hash(landmarks);
  char now[24], recorded[24];
  std::snprintf(now, sizeof(now), "%016" PRIx64, hash);
  std::snprintf(recorded, sizeof(recorded), "%016" PRIx64, area.landmarks_hash);
  LMB_CHECK(static_cast<int64_t>(landmarks.size()) == area.landmarks && hash == area.landmarks_hash,
            area.file << ": area " << area.id << " now has " << landmarks.size() << " landmarks (hash " << now
                      << "), the run's config records " << area.landmarks << " (hash " << recorded
                      << "): the areas file changed since the run started; use the file it was trained with or "
                         "another --out folder");
  return landmarks;
}

}  // namespace lmb
