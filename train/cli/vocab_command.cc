// lboost vocab: trains the binary visual vocabulary on images that are not the map's.
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/detector_options.h"
#include "common/error.h"
#include "common/file_io.h"
#include "common/random.h"
#include "common/vocabulary.h"
#include "train/cli/commands.h"

namespace lmb::cli {

namespace {

struct VocabArgs {
  std::vector<std::string> image_dirs;
  std::string out;
  std::string detector = "BRISK";
  int words = 16;
  uint64_t seed = 7;
  int64_t max_descriptors = 200000;
  int max_iterations = 100;
};

// All images under the folders, recursively, sorted so that the result does not depend on the
// file system's listing order.
std::vector<std::filesystem::path> list_images(const std::vector<std::string>& dirs) {
  std::vector<std::filesystem::path> images;
  for (const std::string& dir : dirs) {
    LMB_CHECK(std::filesystem::is_directory(dir), "--images " << dir << ": not a folder");
    std::vector<std::filesystem::path> found;
    for (const auto& entry : std::filesystem::recursive_directory_iterator(
             dir, std::filesystem::directory_options::follow_directory_symlink)) {
      if (entry.is_regular_file() && is_image_file(entry.path())) found.push_back(entry.path());
    }
    std::sort(found.begin(), found.end());
    LMB_CHECK(!found.empty(), "--images " << dir << ": no images (" << kImageExtensions << ")");
    images.insert(images.end(), found.begin(), found.end());
  }
  return images;
}

void run_vocab(const VocabArgs& a) {
  std::vector<NamedPath> inputs;
  for (const std::string& dir : a.image_dirs) inputs.push_back({dir, "--images", true});
  check_outputs_not_inputs({{a.out, "--out"}}, inputs);
  VocabularyTrainOptions options;
  options.num_words = a.words;
  options.seed = a.seed;
  options.max_iterations = a.max_iterations;
  options.check();
  LMB_CHECK(a.max_descriptors >= a.words,
            "--max-descriptors " << a.max_descriptors << " must be >= --words " << a.words);
  check_writable_file(a.out, "--out");
  cv::Ptr<cv::Feature2D> detector;
  if (a.detector == "BRISK") {
    detector = cv::BRISK::create();
  } else if (a.detector == "ORB") {
    detector = cv::ORB::create(2000);
  } else {
    LMB_FAIL("--detector " << a.detector << ": must be BRISK or ORB");
  }

  // The detectors above have DetectorOptions' defaults (BRISK: 3 octaves): the same smallest image.
  DetectorOptions sizes;
  sizes.detector = a.detector;
  const auto images = list_images(a.image_dirs);
  spdlog::info("vocab: {} images, detector {}", images.size(), a.detector);
  const auto start = std::chrono::steady_clock::now();
  std::vector<uint8_t> descriptors;
  int descriptor_bytes = 0;
  int64_t count = 0;
  for (const auto& path : images) {
    const cv::Mat image = cv::imread(path.string(), cv::IMREAD_GRAYSCALE);
    LMB_CHECK(!image.empty(), path.string() << ": cannot read the image");
    sizes.check_image_size(image.cols, image.rows, path.string());
    std::vector<cv::KeyPoint> keypoints;
    cv::Mat desc;
    try {
      detector->detectAndCompute(image, cv::noArray(), keypoints, desc);
    } catch (const cv::Exception& e) {
      LMB_FAIL(path.string() << ": OpenCV failed on this " << image.cols << "x" << image.rows << " image: " << e.err
                             << " (in " << e.func << ")");
    }
    if (desc.empty()) continue;
    LMB_CHECK(desc.type() == CV_8U, path.string() << ": detector gave non-binary descriptors");
    if (descriptor_bytes == 0) descriptor_bytes = desc.cols;
    LMB_CHECK(desc.cols == descriptor_bytes, path.string() << ": descriptor length changed");
    for (int r = 0; r < desc.rows; ++r) {
      const uint8_t* row = desc.ptr<uint8_t>(r);
      descriptors.insert(descriptors.end(), row, row + descriptor_bytes);
    }
    count += desc.rows;
  }
  LMB_CHECK(count >= a.words, "--images: only " << count << " descriptors found in " << images.size()
                                                << " images; need at least " << a.words);
  // Deterministic subsample (partial Fisher-Yates with lmb::Rng) down to max_descriptors.
  if (count > a.max_descriptors) {
    Rng rng(counter_hash(a.seed, 0x53554253 /* "SUBS" */));
    std::vector<int64_t> index(static_cast<size_t>(count));
    for (int64_t i = 0; i < count; ++i) index[i] = i;
    for (int64_t i = 0; i < a.max_descriptors; ++i) {
      const int64_t j = i + static_cast<int64_t>(rng.below(static_cast<uint64_t>(count - i)));
      std::swap(index[i], index[j]);
    }
    index.resize(static_cast<size_t>(a.max_descriptors));
    std::sort(index.begin(), index.end());
    std::vector<uint8_t> kept(static_cast<size_t>(a.max_descriptors) * descriptor_bytes);
    for (int64_t i = 0; i < a.max_descriptors; ++i) {
      std::copy_n(descriptors.data() + index[i] * descriptor_bytes, descriptor_bytes,
                  kept.data() + i * descriptor_bytes);
    }
    descriptors.swap(kept);
    spdlog::info("vocab: {} descriptors of {} bytes, subsampled to {}", count, descriptor_bytes, a.max_descriptors);
    count = a.max_descriptors;
  } else {
    spdlog::info("vocab: {} descriptors of {} bytes", count, descriptor_bytes);
  }

  VocabularyTrainStats stats;
  const Vocabulary vocabulary =
      train_vocabulary(descriptors.data(), count, descriptor_bytes, options, &stats, [&](int it, int64_t cost) {
        spdlog::info("vocab: iteration {:3d} cost {} (mean {:.3f} bits)", it, cost,
                     static_cast<double>(cost) / static_cast<double>(count));
      });
  vocabulary.save(a.out);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  spdlog::info("vocab: {} words after {} iterations ({}), {} reseeded; wrote {} in {:.1f} s", vocabulary.num_words(),
               stats.iterations, stats.converged ? "converged" : "iteration limit", stats.reseeded_words, a.out,
               seconds);
}

}  // namespace

void add_vocab_command(CLI::App& app) {
  auto args = std::make_shared<VocabArgs>();
  auto* cmd = app.add_subcommand("vocab",
                                 "Train the binary visual vocabulary (k-majority in Hamming space, k-means++ init) on "
                                 "images that are NOT the map's; writes an LMBVOCAB file");
  cmd->add_option("--images", args->image_dirs, "image folder, scanned recursively (repeatable)")->required();
  cmd->add_option("--out", args->out, "output vocabulary file (.lbv)")->required();
  cmd->add_option("--words", args->words, "number of visual words, 4..256")->capture_default_str();
  add_seed_option(cmd, "--seed", &args->seed, "k-means++ and subsampling seed");
  cmd->add_option("--detector", args->detector, "BRISK (64-byte) or ORB (32-byte); use the map's")
      ->capture_default_str();
  cmd->add_option("--max-descriptors", args->max_descriptors, "random subsample of at most this many descriptors")
      ->capture_default_str();
  cmd->add_option("--max-iterations", args->max_iterations, "k-majority iteration limit")->capture_default_str();
  cmd->callback([args] { run_vocab(*args); });
}

}  // namespace lmb::cli
