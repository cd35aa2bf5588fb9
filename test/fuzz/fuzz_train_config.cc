// Fuzz target: TOML training configs (train/boost/train_config.h). A config that is accepted must
// pass TrainConfig::check() and round-trip: the TOML written from it reads back to the same TOML.
#include <cstdint>
#include <string>

#include "test/fuzz/fuzz_util.h"
#include "train/boost/train_config.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  lmb::fuzz::call_loader("apply_train_config_toml", [&] {
    lmb::TrainConfig config;
    lmb::apply_train_config_toml(text, "fuzz.toml", &config);
    config.check();
    const std::string written = lmb::train_config_toml(config);
    lmb::TrainConfig again;
    lmb::apply_train_config_toml(written, "fuzz.toml (written back)", &again);
    if (lmb::train_config_toml(again) != written) __builtin_trap();
  });
  return 0;
}
