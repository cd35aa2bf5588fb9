#include "infer/area_bundle.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <memory>
#include <mutex>

#include "common/error.h"
#include "common/file_container.h"
#include "common/file_io.h"

namespace lmb {

std::shared_ptr<AreaBundle> AreaBundle::open(const std::filesystem::path& index) {
  return create(index, read_bundle_index(index));
}

std::shared_ptr<AreaBundle> AreaBundle::create(const std::filesystem::path& index_path, BundleIndex index) {
  check_bundle_index(index, index_path.string());
  auto bundle = std::shared_ptr<AreaBundle>(new AreaBundle());
  bundle->index_ = index_path;
  bundle->reach_ = index.reach;
  bundle->map_fingerprint_ = index.map_fingerprint;
  bundle->calibration_ = std::move(index.calibration);
  bundle->walk_calibration_ = std::move(index.walk_calibration);
  bundle->areas_ = std::move(index.areas);
  bundle->models_.resize(bundle->areas_.size());
  bundle->last_use_.assign(bundle->areas_.size(), 0);
  bundle->view_samples_.resize(bundle->areas_.size());
  return bundle;
}

void PositionPrior::check() const {
  LMB_CHECK(position.allFinite(), "position prior: the position is not finite");
  LMB_CHECK(std::isfinite(radius) && radius >= 0.0, "position prior: radius " << radius << " must be finite and >= 0");
}

std::vector<int32_t> AreaBundle::select(const PositionPrior* prior) const {
  std::vector<int32_t> ids;
  if (prior != nullptr) prior->check();
  for (const BundleArea& a : areas_) {
    if (prior == nullptr || a.distance(prior->position) <= prior->radius + reach_) ids.push_back(a.id);
  }
  return ids;
}

std::shared_ptr<const Model> AreaBundle::model(int32_t id) {
  LMB_CHECK(id >= 0 && static_cast<size_t>(id) < areas_.size(),
            index_.string() << ": no area " << id << " (the bundle has " << areas_.size() << ")");
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (models_[static_cast<size_t>(id)]) {
      last_use_[static_cast<size_t>(id)] = ++use_clock_;
      return models_[static_cast<size_t>(id)];
    }
  }
  const BundleArea& a = areas_[static_cast<size_t>(id)];
  const std::filesystem::path path = index_.parent_path() / a.file;
  const std::string what = index_.parent_path().string() + ": area " + std::to_string(id) + " (" + a.file + ")";
  std::string image;
  try {
    image = read_file(path, a.bytes + 1);
  } catch (const Error& e) {
    LMB_FAIL(what << ": " << e.what());
  }
  LMB_CHECK(image.size() == a.bytes, what << ": " << image.size() << " bytes, the bundle index says " << a.bytes
                                          << " (a different or damaged file)");
  const uint32_t crc = crc32(reinterpret_cast<const uint8_t*>(image.data()), image.size());
  LMB_CHECK(crc == a.crc32, what << ": CRC-32 mismatch with the bundle index (a different or damaged file)");
  std::shared_ptr<const Model> model =
      Model::from_bytes(reinterpret_cast<const uint8_t*>(image.data()), image.size(), what);
  check_area_model(a, *model, what);
  ModelTransform transform;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    transform = transform_;
  }
  if (transform) {
    const int32_t classes = model->num_classes();
    try {
      model = transform(id, std::move(model));
    } catch (const std::exception& e) {
      LMB_FAIL(what << ": " << e.what());
    }
    LMB_CHECK(model != nullptr && model->num_classes() == classes,
              what << ": the bundle's model transform returned " << (model ? "a model of other classes" : "no model"));
  }
  std::lock_guard<std::mutex> lock(mutex_);
  // One descriptor length for every area: a frame's descriptors are read with it.
  LMB_CHECK(descriptor_bytes_ < 0 || model->descriptor_bytes() == descriptor_bytes_,
            what << ": " << model->descriptor_bytes() << "-byte descriptors, the bundle's areas loaded before have "
                 << descriptor_bytes_);
  descriptor_bytes_ = model->descriptor_bytes();
  const size_t i = static_cast<size_t>(id);
  last_use_[i] = ++use_clock_;
  if (!view_samples_[i]) {
    // Every landmark up to kViewSample, else an even stride over the classes (deterministic).
    auto sample = std::make_shared<std::vector<Eigen::Vector3d>>();
    const size_t n = static_cast<size_t>(model->num_classes());
    const size_t count = std::min(n, kViewSample);
    sample->reserve(count);
    for (size_t k = 0; k < count; ++k) sample->push_back(model->class_position(static_cast<int32_t>(k * n / count)));
    view_samples_[i] = std::move(sample);
  }
  if (!models_[i]) {
    models_[i] = std::move(model);
    ++loads_;
    evict_locked(id);
  }
  return models_[i];
}

void AreaBundle::set_model_transform(ModelTransform transform) {
  std::lock_guard<std::mutex> lock(mutex_);
  transform_ = std::move(transform);
  for (auto& m : models_) m.reset();
}

void AreaBundle::evict_locked(int32_t keep) {
  for (;;) {
    int64_t count = 0;
    uint64_t bytes = 0;
    int32_t oldest = -1;
    for (size_t i = 0; i < models_.size(); ++i) {
      if (!models_[i]) continue;
      ++count;
      bytes += areas_[i].bytes;
      if (static_cast<int32_t>(i) != keep && (oldest < 0 || last_use_[i] < last_use_[static_cast<size_t>(oldest)])) {
        oldest = static_cast<int32_t>(i);
      }
    }
    const bool over =
        (limits_.max_areas > 0 && count > limits_.max_areas) || (limits_.max_bytes > 0 && bytes > limits_.max_bytes);
    if (!over || oldest < 0) return;
    models_[static_cast<size_t>(oldest)].reset();
  }
}

void AreaBundle::set_cache_limits(const BundleCacheLimits& limits) {
  LMB_CHECK(limits.max_areas >= 0, "bundle cache: max_areas = " << limits.max_areas << " must be >= 0 (0 = no limit)");
  std::lock_guard<std::mutex> lock(mutex_);
  limits_ = limits;
  // The most recently used area is kept, as after a load.
  int32_t newest = -1;
  for (size_t i = 0; i < models_.size(); ++i) {
    if (models_[i] && (newest < 0 || last_use_[i] > last_use_[static_cast<size_t>(newest)])) {
      newest = static_cast<int32_t>(i);
    }
  }
  evict_locked(newest);
}

BundleCacheLimits AreaBundle::cache_limits() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return limits_;
}

std::vector<int32_t> AreaBundle::loaded_ids() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<int32_t> ids;
  for (size_t i = 0; i < models_.size(); ++i) {
    if (models_[i]) ids.push_back(static_cast<int32_t>(i));
  }
  return ids;
}

uint64_t AreaBundle::loaded_bytes() const {
  std::lock_guard<std::mutex> lock(mutex_);
  uint64_t bytes = 0;
  for (size_t i = 0; i < models_.size(); ++i) {
    if (models_[i]) bytes += areas_[i].bytes;
  }
  return bytes;
}

int64_t AreaBundle::loads() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return loads_;
}

int32_t AreaBundle::visible_landmarks(int32_t id, const Camera& camera, const Rigid3d& cam_from_world) {
  std::shared_ptr<const std::vector<Eigen::Vector3d>> sample;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (id >= 0 && static_cast<size_t>(id) < view_samples_.size()) sample = view_samples_[static_cast<size_t>(id)];
  }
  if (!sample) {
    model(id);  // loads it (or throws naming it)
    std::lock_guard<std::mutex> lock(mutex_);
    sample = view_samples_[static_cast<size_t>(id)];
  }
  int32_t visible = 0;
  for (const Eigen::Vector3d& p : *sample) {
    const Eigen::Vector3d in_cam = cam_from_world * p;
    Eigen::Vector2d px;
    if (in_cam.z() <= 0.0 || (reach_ > 0.0 && in_cam.norm() > reach_) || !camera.project(in_cam, &px)) continue;
    visible += px.x() >= 0.0 && px.y() >= 0.0 && px.x() < camera.width && px.y() < camera.height;
  }
  return visible;
}

int32_t AreaBundle::descriptor_bytes() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return descriptor_bytes_;
}

int32_t AreaBundle::descriptor_bytes(const std::vector<int32_t>& ids) {
  for (size_t i = 0; descriptor_bytes() < 0 && i < ids.size(); ++i) {
    try {
      model(ids[i]);
    } catch (const Error&) {
      // A missing or damaged area: the next one may tell.
    }
  }
  return descriptor_bytes();
}

bool AreaBundle::loaded(int32_t id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return id >= 0 && static_cast<size_t>(id) < models_.size() && models_[static_cast<size_t>(id)] != nullptr;
}

void AreaBundle::release_except(const std::vector<int32_t>& keep) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (size_t i = 0; i < models_.size(); ++i) {
    if (std::find(keep.begin(), keep.end(), static_cast<int32_t>(i)) == keep.end()) models_[i].reset();
  }
}

}  // namespace lmb
