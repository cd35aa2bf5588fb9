// Fuzz target: model.bin, the trainer's output that `lboost export` reads (train/boost/boost_model.h:
// the stumps and the feature space they were trained in, common/feature_space.h). The input is a
// whole file image, loaded as is and with its length and CRC repaired (see fuzz_util.h). A model
// that loads must be valid, agree with its feature space and save back to the same bytes.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "common/file_io.h"
#include "test/fuzz/fuzz_util.h"
#include "train/boost/boost_model.h"

namespace {

void load_and_use(const std::vector<uint8_t>& image) {
  const auto path = lmb::fuzz::scratch_dir() / "model.bin";
  lmb::fuzz::write_file(path, std::string(image.begin(), image.end()));
  const lmb::TrainedModel t = lmb::load_trained_model(path);
  t.model.check();
  if (t.model.num_dims != t.feature_space.num_dims) __builtin_trap();
  const auto again = lmb::fuzz::scratch_dir() / "again.bin";
  lmb::save_trained_model(again, t.model, t.feature_space);
  const lmb::TrainedModel u = lmb::load_trained_model(again);
  if (!(u.model == t.model) || !lmb::feature_space_difference(t.feature_space, u.feature_space).empty()) {
    __builtin_trap();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  lmb::fuzz::call_loader("load_trained_model", [&] { load_and_use(std::vector<uint8_t>(data, data + size)); });
  lmb::fuzz::call_loader("load_trained_model (repaired header)",
                         [&] { load_and_use(lmb::fuzz::with_repaired_header(data, size)); });
  return 0;
}
