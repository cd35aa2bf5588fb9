#include "common/vocabulary.h"

#include <filesystem>
#include <fstream>
#include <limits>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/hamming.h"
#include "common/random.h"

namespace lmb {
namespace {

// Descriptors scattered around `k` random centres: each bit flipped with probability `flip`.
std::vector<uint8_t> clustered(int k, int64_t n, int bytes, double flip, uint64_t seed) {
  Rng rng(seed);
  std::vector<uint8_t> centres(static_cast<size_t>(k) * bytes);
  for (auto& c : centres) c = static_cast<uint8_t>(rng.below(256));
  std::vector<uint8_t> x(static_cast<size_t>(n) * bytes);
  for (int64_t i = 0; i < n; ++i) {
    const uint64_t c = rng.below(k);
    for (int b = 0; b < bytes; ++b) {
      uint8_t v = centres[c * bytes + b];
      for (int bit = 0; bit < 8; ++bit) {
        if (rng.uniform() < flip) v = static_cast<uint8_t>(v ^ (1u << bit));
      }
      x[i * bytes + b] = v;
    }
  }
  return x;
}

std::filesystem::path temp_path(const std::string& name) {
  return std::filesystem::temp_directory_path() / ("lmb_vocab_test_" + std::to_string(::getpid()) + "_" + name);
}

TEST(Vocabulary, TrainingCostNeverIncreasesDecreasesOverallAndIsDeterministic) {
  const int bytes = 64;
  const auto x = clustered(24, 6000, bytes, 0.15, 3);
  VocabularyTrainOptions o;
  o.num_words = 16;
  o.seed = 7;
  VocabularyTrainStats s1, s2;
  std::vector<int64_t> logged;
  const Vocabulary v1 = train_vocabulary(x.data(), 6000, bytes, o, &s1, [&](int, int64_t c) { logged.push_back(c); });
  const Vocabulary v2 = train_vocabulary(x.data(), 6000, bytes, o, &s2);
  ASSERT_GE(s1.cost.size(), 2u);
  EXPECT_EQ(logged, s1.cost);
  for (size_t i = 1; i < s1.cost.size(); ++i) EXPECT_LE(s1.cost[i], s1.cost[i - 1]) << i;
  EXPECT_LT(s1.cost.back(), s1.cost.front());
  EXPECT_TRUE(s1.converged);
  EXPECT_EQ(v1, v2);
  EXPECT_EQ(s1.cost, s2.cost);
  EXPECT_EQ(v1.num_words(), 16);
  EXPECT_EQ(v1.descriptor_bytes(), bytes);

  // The reported cost is the real cost of the result.
  int64_t cost = 0;
  for (int64_t i = 0; i < 6000; ++i) {
    const uint8_t* d = x.data() + i * bytes;
    cost += hamming_distance(d, v1.word(v1.quantize(d)), bytes);
  }
  EXPECT_EQ(cost, s1.cost.back());

  o.seed = 8;
  EXPECT_FALSE(train_vocabulary(x.data(), 6000, bytes, o) == v1);
}

TEST(Vocabulary, RecoversWellSeparatedClusters) {
  // 4 clusters with 2% bit noise: every cluster's descriptors end in one word of their own.
  const int bytes = 32;
  Rng rng(1);
  const auto x = clustered(4, 2000, bytes, 0.02, 9);
  VocabularyTrainOptions o;
  o.num_words = 4;
  VocabularyTrainStats s;
  const Vocabulary v = train_vocabulary(x.data(), 2000, bytes, o, &s);
  // Average distance to the word is about the noise level (0.02 * 256 bits = 5).
  EXPECT_LT(static_cast<double>(s.cost.back()) / 2000.0, 8.0);
}

TEST(Vocabulary, QuantizeEqualsBruteForceWithLowestIndexOnTies) {
  const int bytes = 64;
  const auto x = clustered(16, 3000, bytes, 0.3, 5);
  VocabularyTrainOptions o;
  o.num_words = 32;
  const Vocabulary v = train_vocabulary(x.data(), 3000, bytes, o);
  const auto queries = clustered(16, 2000, bytes, 0.4, 6);
  std::vector<uint8_t> out(2000);
  v.quantize(queries.data(), 2000, out.data());
  for (int64_t i = 0; i < 2000; ++i) {
    const uint8_t* q = queries.data() + i * bytes;
    int best = -1, best_d = std::numeric_limits<int>::max();
    for (int w = 0; w < v.num_words(); ++w) {
      int d = 0;
      for (int bit = 0; bit < 8 * bytes; ++bit) d += descriptor_bit(q, bit) != descriptor_bit(v.word(w), bit);
      if (d < best_d) best_d = d, best = w;
    }
    ASSERT_EQ(out[i], best) << i;
    ASSERT_EQ(v.quantize(q), best);
  }
  // An exact tie: words 1 and 2 are equal, a query equal to them goes to 1.
  std::vector<uint8_t> words(4 * 4, 0);
  for (int b = 0; b < 4; ++b) words[4 + b] = words[8 + b] = 0xF0, words[12 + b] = 0xFF;
  const Vocabulary tie(4, words);
  const uint8_t q[4] = {0xF0, 0xF0, 0xF0, 0xF0};
  EXPECT_EQ(tie.quantize(q), 1);
}

TEST(Vocabulary, FileRoundTripAndRejections) {
  const auto x = clustered(8, 500, 64, 0.1, 2);
  const Vocabulary v = train_vocabulary(x.data(), 500, 64, VocabularyTrainOptions{});
  const auto path = temp_path("ok.lbv");
  v.save(path);
  EXPECT_EQ(Vocabulary::load(path), v);

  // Another descriptor length.
  EXPECT_NO_THROW(v.check_descriptor_bytes(64, "map.h5"));
  EXPECT_THROW(v.check_descriptor_bytes(32, "map.h5"), Error);
  EXPECT_THROW(Vocabulary().check_descriptor_bytes(64, "map.h5"), Error);

  // A damaged byte: CRC error.
  std::string bytes;
  {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  std::string damaged = bytes;
  damaged[damaged.size() - 3] ^= 0x10;
  const auto bad_path = temp_path("bad.lbv");
  {
    std::ofstream out(bad_path, std::ios::binary);
    out << damaged;
  }
  EXPECT_THROW(Vocabulary::load(bad_path), Error);
  // Payload with a word count out of range, and a payload too short for its counts.
  std::string payload = v.to_payload();
  std::string p1 = payload;
  const int32_t huge = 100000;
  p1.replace(1, 4, reinterpret_cast<const char*>(&huge), 4);
  EXPECT_THROW(Vocabulary::from_payload(p1, "x"), Error);
  EXPECT_THROW(Vocabulary::from_payload(payload.substr(0, payload.size() - 1), "x"), Error);
  EXPECT_THROW(Vocabulary::from_payload(payload.substr(0, 3), "x"), Error);
  EXPECT_EQ(Vocabulary::from_payload(payload, "x"), v);
  EXPECT_THROW(Vocabulary::load(temp_path("missing.lbv")), Error);
  std::filesystem::remove(path);
  std::filesystem::remove(bad_path);
}

// Regression (found by test/fuzz/fuzz_vocabulary): a file whose valid header wraps an empty or
// short payload made cereal throw its own exception instead of lmb::Error. The first case is the
// fuzzer's input: "LMBVOCAB", version 1, payload length 0, CRC 0.
TEST(Vocabulary, EmptyOrShortPayloadIsAnErrorNotACrash) {
  const auto path = temp_path("short.lbv");
  const std::string fuzz_input("LMBVOCAB\x01\0\0\0\0\0\0\0\0\0\0\0\0\0\0\0", 24);
  {
    std::ofstream out(path, std::ios::binary);
    out << fuzz_input;
  }
  try {
    Vocabulary::load(path);
    ADD_FAILURE() << "an empty payload was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              path.string() + ": truncated vocabulary header (0 payload bytes, expected at least 9)");
  }
  const std::string payload = Vocabulary(8, std::vector<uint8_t>(4 * 8, 7)).to_payload();
  for (size_t n = 0; n < 9; ++n) {
    EXPECT_THROW(Vocabulary::from_payload(payload.substr(0, n), "short.lbv"), Error) << n << " bytes";
  }
  std::filesystem::remove(path);
}

TEST(Vocabulary, BadOptionsAndInputsThrow) {
  const auto x = clustered(4, 10, 8, 0.1, 2);
  VocabularyTrainOptions o;
  o.num_words = 3;
  EXPECT_THROW(o.check(), Error);
  o.num_words = 257;
  EXPECT_THROW(o.check(), Error);
  o.num_words = 16;
  EXPECT_THROW(train_vocabulary(x.data(), 10, 8, o), Error);  // fewer descriptors than words
  EXPECT_THROW(Vocabulary(8, std::vector<uint8_t>(3 * 8)), Error);
  EXPECT_THROW(Vocabulary(8, std::vector<uint8_t>(4 * 8 + 1)), Error);
  EXPECT_THROW(Vocabulary(0, std::vector<uint8_t>()), Error);
}

TEST(Vocabulary, IdenticalDescriptorsStillGiveAValidVocabulary) {
  std::vector<uint8_t> x(100 * 8, 0xAB);
  VocabularyTrainOptions o;
  o.num_words = 4;
  VocabularyTrainStats s;
  const Vocabulary v = train_vocabulary(x.data(), 100, 8, o, &s);
  EXPECT_EQ(s.cost.back(), 0);
  EXPECT_EQ(v.quantize(x.data()), 0);
}

}  // namespace
}  // namespace lmb
