// Fuzz target: training checkpoints (train/checkpoint/checkpoint_h5.h), read when a run resumes. The
// input bytes are written to a scratch ckpt file and read with read_checkpoint.
#include <cstdint>
#include <string_view>

#include <H5Cpp.h>

#include "test/fuzz/fuzz_util.h"
#include "train/checkpoint/checkpoint_h5.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool quiet = [] {
    H5::Exception::dontPrint();
    return true;
  }();
  (void)quiet;
  const auto path = lmb::fuzz::scratch_dir() / "ckpt-0000001.h5";
  lmb::fuzz::write_file(path, std::string_view(reinterpret_cast<const char*>(data), size));
  lmb::fuzz::call_loader("read_checkpoint", [&] { lmb::read_checkpoint(path); });
  return 0;
}
