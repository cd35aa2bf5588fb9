// The binary visual vocabulary: K words (binary descriptors) learned by k-majority (k-means in
// Hamming space: assign each descriptor to its nearest word, set each word to the bitwise majority
// of its descriptors). Quantizing a descriptor returns the nearest word by Hamming distance, ties
// going to the lowest word index.
//
// File (`lboost vocab --out vocab.lbv`): lmb container (common/file_container.h) with magic
// "LMBVOCAB", version 1; payload = cereal portable binary of
//   int32 num_words (4..256), int32 descriptor_bytes (1..kMaxDescriptorBytes),
//   num_words * descriptor_bytes bytes of words (row after row, bits LSB-first as OpenCV packs them).
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace lmb {

constexpr const char* kVocabularyMagic = "LMBVOCAB";
constexpr uint32_t kVocabularyVersion = 1;
constexpr int kMinVocabularyWords = 4;
constexpr int kMaxVocabularyWords = 256;  // a word index fits in uint8_t
constexpr int kMaxDescriptorBytes = 1024;

class Vocabulary {
 public:
  Vocabulary() = default;
  // `words` holds num_words * descriptor_bytes bytes. Throws lmb::Error when the word count is
  // outside 4..256, descriptor_bytes outside 1..kMaxDescriptorBytes or the size does not match.
  Vocabulary(int descriptor_bytes, std::vector<uint8_t> words);

  int num_words() const { return num_words_; }
  int descriptor_bytes() const { return descriptor_bytes_; }
  const uint8_t* word(int w) const { return words_.data() + static_cast<size_t>(w) * descriptor_bytes_; }
  const std::vector<uint8_t>& words() const { return words_; }

  // Nearest word of one descriptor of descriptor_bytes() bytes; ties -> lowest index.
  int quantize(const uint8_t* descriptor) const;
  // Words of n descriptors stored as flat rows of descriptor_bytes() bytes; out has n entries.
  void quantize(const uint8_t* descriptors, int64_t n, uint8_t* out) const;

  // Throws lmb::Error naming `what` when descriptors of `bytes` bytes cannot be quantized with this
  // vocabulary (another descriptor length, or an empty vocabulary).
  void check_descriptor_bytes(int bytes, const std::string& what) const;

  // File I/O (format above). load() throws lmb::Error naming the path: container errors (magic,
  // version, length, CRC), counts out of range, payload size mismatch.
  void save(const std::filesystem::path& path) const;
  static Vocabulary load(const std::filesystem::path& path);
  // The payload alone (what save() wraps in the container).
  std::string to_payload() const;
  static Vocabulary from_payload(const std::string& payload, const std::string& what);

  bool operator==(const Vocabulary& o) const {
    return num_words_ == o.num_words_ && descriptor_bytes_ == o.descriptor_bytes_ && words_ == o.words_;
  }

 private:
  int num_words_ = 0;
  int descriptor_bytes_ = 0;
  std::vector<uint8_t> words_;
};

struct VocabularyTrainOptions {
  int num_words = 16;        // K, 4..256
  uint64_t seed = 7;         // k-means++ initialisation
  int max_iterations = 100;  // stops earlier when no assignment changes

  // Throws lmb::Error naming the field.
  void check() const;
};

struct VocabularyTrainStats {
  // Sum over descriptors of the Hamming distance to their word: after initialisation (entry 0) and
  // after each iteration (assignment + majority update). Non-increasing.
  std::vector<int64_t> cost;
  int iterations = 0;
  bool converged = false;  // an iteration changed no assignment
  int reseeded_words = 0;  // empty clusters moved to the worst-fit descriptor
};

// Trains a vocabulary on n descriptors (flat rows of descriptor_bytes bytes). Deterministic for a
// seed (single-threaded). Initialisation: k-means++ (first word uniform, then D^2 sampling with
// lmb::Rng); a majority tie keeps the word's previous bit, so the cost never increases; an empty
// cluster takes the descriptor farthest from its word (lowest index on ties). `on_iteration`, if
// set, is called with (iteration, cost) after each iteration (iteration 0 = initialisation).
// Throws lmb::Error when n < num_words or the options are invalid.
Vocabulary train_vocabulary(const uint8_t* descriptors, int64_t n, int descriptor_bytes,
                            const VocabularyTrainOptions& options, VocabularyTrainStats* stats = nullptr,
                            const std::function<void(int, int64_t)>& on_iteration = {});

}  // namespace lmb
