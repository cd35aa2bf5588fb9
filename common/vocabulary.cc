#include "common/vocabulary.h"

#include <algorithm>
#include <limits>
#include <sstream>

#include <cereal/archives/portable_binary.hpp>

#include "common/error.h"
#include "common/file_container.h"
#include "common/hamming.h"
#include "common/random.h"

namespace lmb {

Vocabulary::Vocabulary(int descriptor_bytes, std::vector<uint8_t> words)
    : descriptor_bytes_(descriptor_bytes), words_(std::move(words)) {
  LMB_CHECK(descriptor_bytes >= 1 && descriptor_bytes <= kMaxDescriptorBytes,
            "vocabulary: descriptor_bytes = " << descriptor_bytes << " must be in 1.." << kMaxDescriptorBytes);
  LMB_CHECK(words_.size() % static_cast<size_t>(descriptor_bytes) == 0,
            "vocabulary: " << words_.size() << " bytes of words are not a multiple of " << descriptor_bytes);
  const size_t k = words_.size() / static_cast<size_t>(descriptor_bytes);
  LMB_CHECK(k >= static_cast<size_t>(kMinVocabularyWords) && k <= static_cast<size_t>(kMaxVocabularyWords),
            "vocabulary: " << k << " words; must be in " << kMinVocabularyWords << ".." << kMaxVocabularyWords);
  num_words_ = static_cast<int>(k);
}

int Vocabulary::quantize(const uint8_t* descriptor) const {
  // The distances to every word through hamming_rows (popcnt where the CPU has it: a libgcc
  // call per 64 bits otherwise), then the first nearest word.
  uint16_t distance[kMaxVocabularyWords];
  hamming_rows(descriptor, words_.data(), num_words_, descriptor_bytes_, distance);
  return static_cast<int>(std::min_element(distance, distance + num_words_) - distance);
}

void Vocabulary::quantize(const uint8_t* descriptors, int64_t n, uint8_t* out) const {
  for (int64_t i = 0; i < n; ++i) {
    out[i] = static_cast<uint8_t>(quantize(descriptors + i * descriptor_bytes_));
  }
}

void Vocabulary::check_descriptor_bytes(int bytes, const std::string& what) const {
  LMB_CHECK(num_words_ > 0, what << ": the vocabulary is empty");
  LMB_CHECK(bytes == descriptor_bytes_, what << ": descriptors of " << bytes
                                             << " bytes, but the vocabulary's words have " << descriptor_bytes_
                                             << " bytes (another detector?)");
}

std::string Vocabulary::to_payload() const {
  std::ostringstream os;
  {
    cereal::PortableBinaryOutputArchive ar(os);
    const int32_t k = num_words_, b = descriptor_bytes_;
    ar(k, b);
    ar(cereal::binary_data(words_.data(), words_.size()));
  }
  return os.str();
}

Vocabulary Vocabulary::from_payload(const std::string& payload, const std::string& what) {
  // The portable binary archive starts with one endianness byte (read by the archive's
  // constructor), then the two int32 counts.
  const size_t header = 1 + 2 * sizeof(int32_t);
  LMB_CHECK(payload.size() >= header, what << ": truncated vocabulary header (" << payload.size()
                                           << " payload bytes, expected at least " << header << ")");
  std::istringstream is(payload);
  cereal::PortableBinaryInputArchive ar(is);
  int32_t k = 0, b = 0;
  ar(k, b);
  LMB_CHECK(k >= kMinVocabularyWords && k <= kMaxVocabularyWords,
            what << ": num_words = " << k << " must be in " << kMinVocabularyWords << ".." << kMaxVocabularyWords);
  LMB_CHECK(b >= 1 && b <= kMaxDescriptorBytes,
            what << ": descriptor_bytes = " << b << " must be in 1.." << kMaxDescriptorBytes);
  const size_t body = static_cast<size_t>(k) * static_cast<size_t>(b);
  LMB_CHECK(payload.size() == header + body, what << ": payload of " << payload.size() << " bytes, expected "
                                                  << header + body << " for " << k << " words of " << b << " bytes");
  std::vector<uint8_t> words(body);
  ar(cereal::binary_data(words.data(), words.size()));
  return Vocabulary(b, std::move(words));
}

void Vocabulary::save(const std::filesystem::path& path) const {
  LMB_CHECK(num_words_ > 0, path.string() << ": cannot save an empty vocabulary");
  write_container_file(path, kVocabularyMagic, kVocabularyVersion, to_payload());
}

Vocabulary Vocabulary::load(const std::filesystem::path& path) {
  const std::string payload = read_container_file(path, kVocabularyMagic, kVocabularyVersion);
  return from_payload(payload, path.string());
}

void VocabularyTrainOptions::check() const {
  LMB_CHECK(
      num_words >= kMinVocabularyWords && num_words <= kMaxVocabularyWords,
      "vocabulary: words = " << num_words << " must be in " << kMinVocabularyWords << ".." << kMaxVocabularyWords);
  LMB_CHECK(max_iterations >= 1 && max_iterations <= 100000,
            "vocabulary: max_iterations = " << max_iterations << " must be in 1..100000");
}

namespace {

// Nearest word of every descriptor; returns the total cost and the number of changed assignments.
int64_t assign(const uint8_t* x, int64_t n, int bytes, const std::vector<uint8_t>& words, int k,
               std::vector<int32_t>& assignment, std::vector<int32_t>& distance, int64_t* changed) {
  int64_t cost = 0;
  int64_t num_changed = 0;
  for (int64_t i = 0; i < n; ++i) {
    const uint8_t* d = x + i * bytes;
    int best = 0;
    int best_distance = std::numeric_limits<int>::max();
    for (int w = 0; w < k; ++w) {
      const int dist = hamming_distance(d, words.data() + static_cast<size_t>(w) * bytes, bytes);
      if (dist < best_distance) {
        best_distance = dist;
        best = w;
      }
    }
    num_changed += assignment[i] != best;
    assignment[i] = best;
    distance[i] = best_distance;
    cost += best_distance;
  }
  *changed = num_changed;
  return cost;
}

}  // namespace

Vocabulary train_vocabulary(const uint8_t* descriptors, int64_t n, int descriptor_bytes,
                            const VocabularyTrainOptions& options, VocabularyTrainStats* stats,
                            const std::function<void(int, int64_t)>& on_iteration) {
  options.check();
  const int k = options.num_words;
  const int bytes = descriptor_bytes;
  LMB_CHECK(bytes >= 1 && bytes <= kMaxDescriptorBytes,
            "vocabulary: descriptor_bytes = " << bytes << " must be in 1.." << kMaxDescriptorBytes);
  LMB_CHECK(n >= k, "vocabulary: " << n << " training descriptors for " << k
                                   << " words; need at least as many descriptors as words");
  VocabularyTrainStats local_stats;
  VocabularyTrainStats& st = stats ? *stats : local_stats;
  st = VocabularyTrainStats{};

  // k-means++ initialisation with D^2 weights (squared Hamming distance to the nearest chosen word).
  Rng rng(counter_hash(options.seed, 0x564F4342 /* "VOCB" */));
  std::vector<uint8_t> words(static_cast<size_t>(k) * bytes);
  std::vector<int64_t> nearest(static_cast<size_t>(n), std::numeric_limits<int64_t>::max());
  int64_t first = static_cast<int64_t>(rng.below(static_cast<uint64_t>(n)));
  std::copy_n(descriptors + first * bytes, bytes, words.begin());
  for (int w = 1; w < k; ++w) {
    const uint8_t* prev = words.data() + static_cast<size_t>(w - 1) * bytes;
    uint64_t total = 0;
    for (int64_t i = 0; i < n; ++i) {
      const int64_t d = hamming_distance(descriptors + i * bytes, prev, bytes);
      nearest[i] = std::min(nearest[i], d * d);
      total += static_cast<uint64_t>(nearest[i]);
    }
    int64_t pick = 0;
    if (total == 0) {
      // Every descriptor equals a chosen word: take any (duplicates are fixed up below).
      pick = static_cast<int64_t>(rng.below(static_cast<uint64_t>(n)));
    } else {
      uint64_t target = rng.below(total);
      for (int64_t i = 0; i < n; ++i) {
        const uint64_t v = static_cast<uint64_t>(nearest[i]);
        if (target < v) {
          pick = i;
          break;
        }
        target -= v;
      }
    }
    std::copy_n(descriptors + pick * bytes, bytes, words.begin() + static_cast<size_t>(w) * bytes);
  }

  std::vector<int32_t> assignment(static_cast<size_t>(n), -1);
  std::vector<int32_t> distance(static_cast<size_t>(n), 0);
  int64_t changed = 0;
  int64_t cost = assign(descriptors, n, bytes, words, k, assignment, distance, &changed);
  st.cost.push_back(cost);
  if (on_iteration) on_iteration(0, cost);

  const int bits = bytes * 8;
  std::vector<int64_t> ones(static_cast<size_t>(k) * bits);
  std::vector<int64_t> members(static_cast<size_t>(k));
  for (int it = 1; it <= options.max_iterations; ++it) {
    // Majority update: word bit = 1 when more than half of its members have it, 0 when fewer,
    // unchanged on a tie; an empty cluster takes the worst-fit descriptor.
    std::fill(ones.begin(), ones.end(), 0);
    std::fill(members.begin(), members.end(), 0);
    for (int64_t i = 0; i < n; ++i) {
      const int w = assignment[i];
      ++members[w];
      int64_t* o = ones.data() + static_cast<size_t>(w) * bits;
      const uint8_t* d = descriptors + i * bytes;
      for (int byte = 0; byte < bytes; ++byte) {
        const unsigned v = d[byte];
        if (v == 0) continue;
        for (int b = 0; b < 8; ++b) o[byte * 8 + b] += (v >> b) & 1u;
      }
    }
    for (int w = 0; w < k; ++w) {
      uint8_t* word = words.data() + static_cast<size_t>(w) * bytes;
      if (members[w] == 0) {
        int64_t worst = 0;
        for (int64_t i = 1; i < n; ++i) {
          if (distance[i] > distance[worst]) worst = i;
        }
        std::copy_n(descriptors + worst * bytes, bytes, word);
        distance[worst] = 0;  // do not hand the same descriptor to two empty clusters
        ++st.reseeded_words;
        continue;
      }
      const int64_t* o = ones.data() + static_cast<size_t>(w) * bits;
      for (int bit = 0; bit < bits; ++bit) {
        const int64_t twice = 2 * o[bit];
        if (twice > members[w]) {
          word[bit >> 3] = static_cast<uint8_t>(word[bit >> 3] | (1u << (bit & 7)));
        } else if (twice < members[w]) {
          word[bit >> 3] = static_cast<uint8_t>(word[bit >> 3] & ~(1u << (bit & 7)));
        }
      }
    }
    cost = assign(descriptors, n, bytes, words, k, assignment, distance, &changed);
    st.cost.push_back(cost);
    st.iterations = it;
    if (on_iteration) on_iteration(it, cost);
    if (changed == 0) {
      st.converged = true;
      break;
    }
  }
  return Vocabulary(bytes, std::move(words));
}

}  // namespace lmb
