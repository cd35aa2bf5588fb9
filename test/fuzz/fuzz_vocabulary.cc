// Fuzz target: the vocabulary file vocab.lbv (common/vocabulary.h). The input is a whole file
// image, read as is and with its length and CRC repaired (see fuzz_util.h); a vocabulary that
// loads must quantize a descriptor to a word in range and write back the same payload.
#include <cstdint>
#include <string>
#include <vector>

#include "common/file_container.h"
#include "common/vocabulary.h"
#include "test/fuzz/fuzz_util.h"

namespace {

void load_and_use(const std::vector<uint8_t>& image) {
  const std::string payload =
      lmb::open_container(image.data(), image.size(), lmb::kVocabularyMagic, lmb::kVocabularyVersion, "fuzz.lbv");
  const lmb::Vocabulary vocab = lmb::Vocabulary::from_payload(payload, "fuzz.lbv");
  const std::vector<uint8_t> descriptor(static_cast<size_t>(vocab.descriptor_bytes()), 0x5A);
  const int w = vocab.quantize(descriptor.data());
  if (w < 0 || w >= vocab.num_words()) __builtin_trap();
  if (vocab.to_payload() != payload) __builtin_trap();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  lmb::fuzz::call_loader("Vocabulary", [&] { load_and_use(std::vector<uint8_t>(data, data + size)); });
  lmb::fuzz::call_loader("Vocabulary (repaired header)",
                         [&] { load_and_use(lmb::fuzz::with_repaired_header(data, size)); });
  return 0;
}
