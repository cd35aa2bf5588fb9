// Fuzz target: model.lbm (infer/model.h), the file apps load on devices. The input is a whole file
// image; it is loaded as is (container checks) and again with its length and CRC repaired (payload
// parser and ModelData::check). A model that loads must also classify a small frame.
#include <cstdint>
#include <vector>

#include "common/context_embedding.h"
#include "infer/classifier.h"
#include "infer/model.h"
#include "test/fuzz/fuzz_util.h"

namespace {

// Classifies 3 keypoints with random-looking descriptors, dense and through the inverted file.
void classify_small_frame(const std::shared_ptr<const lmb::Model>& model) {
  const int32_t bytes = model->descriptor_bytes();
  std::vector<uint8_t> descriptors(static_cast<size_t>(3) * bytes);
  for (size_t i = 0; i < descriptors.size(); ++i) descriptors[i] = static_cast<uint8_t>(i * 37 + 11);
  lmb::FrameKeypoints frame;
  frame.x = {0.0f, 0.1f, -0.2f};
  frame.y = {0.0f, -0.1f, 0.3f};
  frame.scale = {0.01f, 0.02f, 0.05f};
  for (int k = 0; k < 3; ++k) {
    frame.word.push_back(static_cast<uint8_t>(model->vocabulary().quantize(descriptors.data() + k * bytes)));
  }
  for (bool inverted : {false, true}) {
    lmb::ClassifierOptions options;
    options.top_k = 2;
    options.use_inverted_file = inverted;
    options.min_margin = -1e300;
    lmb::Classifier classifier(model, options);
    const lmb::KeypointMatches matches = classifier.classify(frame, descriptors.data());
    if (matches.num_keypoints() != 3) __builtin_trap();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  lmb::fuzz::call_loader("Model::from_bytes",
                         [&] { classify_small_frame(lmb::Model::from_bytes(data, size, "fuzz.lbm")); });
  const std::vector<uint8_t> repaired = lmb::fuzz::with_repaired_header(data, size);
  lmb::fuzz::call_loader("Model::from_bytes (repaired header)", [&] {
    classify_small_frame(lmb::Model::from_bytes(repaired.data(), repaired.size(), "fuzz.lbm"));
  });
  return 0;
}
