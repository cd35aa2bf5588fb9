// Fuzz target: the bundle index bundle.txt (infer/area_bundle.h, AreaBundle::open), which apps read
// beside the area models. A bundle that opens must have at least one area, ids equal to their
// positions and a finite reach >= 0; selecting areas (without and with valid priors) gives
// ascending ids of the bundle and no error; loading an area (whose model file is missing or not
// what the index says) returns a model or throws lmb::Error.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <memory>
#include <string_view>
#include <vector>

#include "infer/area_bundle.h"
#include "test/fuzz/fuzz_util.h"

namespace {

void check_selection(const lmb::AreaBundle& bundle, const lmb::PositionPrior* prior) {
  std::vector<int32_t> ids;
  try {
    ids = bundle.select(prior);
  } catch (const lmb::Error& e) {
    std::fprintf(stderr, "fuzz: AreaBundle::select with a valid prior threw: %s\n", e.what());
    __builtin_trap();
  }
  const size_t n = bundle.areas().size();
  if (prior == nullptr && ids.size() != n) __builtin_trap();
  for (size_t i = 0; i < ids.size(); ++i) {
    if (ids[i] < 0 || static_cast<size_t>(ids[i]) >= n || (i > 0 && ids[i] <= ids[i - 1])) __builtin_trap();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = lmb::fuzz::scratch_dir() / "bundle.txt";
  lmb::fuzz::write_file(path, std::string_view(reinterpret_cast<const char*>(data), size));
  std::shared_ptr<lmb::AreaBundle> bundle;
  if (!lmb::fuzz::call_loader("AreaBundle::open", [&] { bundle = lmb::AreaBundle::open(path); })) return 0;
  if (bundle->areas().empty() || !std::isfinite(bundle->reach()) || bundle->reach() < 0.0) __builtin_trap();
  for (size_t i = 0; i < bundle->areas().size(); ++i) {
    if (bundle->areas()[i].id != static_cast<int32_t>(i)) __builtin_trap();
  }
  check_selection(*bundle, nullptr);
  const double big = std::numeric_limits<double>::max();
  for (const lmb::PositionPrior& prior :
       {lmb::PositionPrior{Eigen::Vector3d::Zero(), 0.0}, lmb::PositionPrior{Eigen::Vector3d(1.5, -2.0, 0.25), 10.0},
        lmb::PositionPrior{Eigen::Vector3d(big, -big, big), big}}) {
    check_selection(*bundle, &prior);
  }
  lmb::fuzz::call_loader("AreaBundle::model", [&] { bundle->model(0); });
  return 0;
}
