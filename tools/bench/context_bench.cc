// `lboost-bench context`: the time to build every training feature vector (landmark keypoints and
// background samples) and to compute only a model's used dims, each against the naive regions x
// keypoints loop on the same samples (docs/inference.md).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <memory>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "common/context_embedding.h"
#include "common/context_regions.h"
#include "common/error.h"
#include "common/file_io.h"
#include "common/io/map_h5.h"
#include "common/machine_info.h"
#include "common/random.h"
#include "common/vocabulary.h"
#include "tools/bench/bench_commands.h"
#include "train/cli/cli_util.h"
#include "train/features/build_features.h"

namespace lmb::bench {

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }
struct ContextBenchArgs {
  std::string map_path;
  std::string vocab_path;
  int synthetic_frames = 0;
  int synthetic_keypoints = 1000;
  double synthetic_landmark_fraction = 0.3;
  int threads = 2;
  int regions = 1000;
  uint64_t region_seed = 1;
  double background_ratio = 1.0;
  int used_dims = 2000;
  int naive_samples = 200;
  int used_dims_frames = 10;
  uint64_t seed = 1;
  std::string json_path;
};

// A map of random frames: a VGA pinhole camera, keypoints uniform over the image with BRISK-like
// sizes (12..48 px, log-uniform), random 64-byte descriptors, gravity rolled by up to +-30 degrees
// and tilted, a fraction of the keypoints observing landmarks (~10 observations each).
LandmarkMap synthetic_map(const ContextBenchArgs& a) {
  Rng rng(counter_hash(a.seed, 0x53594E54 /* "SYNT" */));
  LandmarkMap map;
  map.detector = "BRISK";
  map.descriptor_bytes = 64;
  Camera cam;
  cam.model = CameraModel::kPinhole;
  cam.width = 640;
  cam.height = 480;
  cam.params = {500, 500, 320, 240};
  map.cameras.push_back(cam);
  const int64_t total = static_cast<int64_t>(a.synthetic_frames) * a.synthetic_keypoints;
  const int64_t positives = static_cast<int64_t>(std::llround(total * a.synthetic_landmark_fraction));
  const int64_t num_landmarks = std::max<int64_t>(1, positives / 10);
  map.landmarks.resize(static_cast<size_t>(num_landmarks));
  map.keypoints.reserve(static_cast<size_t>(total));
  map.descriptors.resize(static_cast<size_t>(total) * 64);
  for (auto& b : map.descriptors) b = static_cast<uint8_t>(rng.below(256));
  for (int f = 0; f < a.synthetic_frames; ++f) {
    MapFrame frame;
    frame.name = "synthetic/" + std::to_string(f);
    frame.first_keypoint = static_cast<int64_t>(map.keypoints.size());
    frame.num_keypoints = a.synthetic_keypoints;
    const double roll = rng.uniform(-M_PI / 6, M_PI / 6), tilt = rng.uniform(-0.5, 0.5);
    frame.gravity_in_cam = Eigen::Vector3d(std::sin(roll), std::cos(roll), tilt).normalized();
    map.frames.push_back(frame);
    for (int k = 0; k < a.synthetic_keypoints; ++k) {
      Keypoint kp;
      kp.x = static_cast<float>(rng.uniform(0, 639));
      kp.y = static_cast<float>(rng.uniform(0, 479));
      kp.scale = static_cast<float>(std::exp(rng.uniform(std::log(12.0), std::log(48.0))));
      map.keypoints.push_back(kp);
      map.keypoint_landmark.push_back(rng.uniform() < a.synthetic_landmark_fraction
                                          ? static_cast<landmark_t>(rng.below(static_cast<uint64_t>(num_landmarks)))
                                          : kInvalidLandmarkId);
    }
  }
  return map;
}

struct NaiveTimes {
  double naive_per_sample = 0, fast_per_sample = 0;  // CPU seconds
  size_t samples = 0;
};

// The naive regions x keypoints loop against the fast path (frame index built for each sample's
// frame) on the same random subset of at most naive_samples samples, both single-threaded; they
// must give the same bytes.
NaiveTimes time_naive_and_fast(const LandmarkMap& map, const ContextRegions& regions, const EmbeddingLayout& layout,
                               const std::vector<uint8_t>& words, const std::vector<int64_t>& samples,
                               int64_t naive_samples, Rng& rng) {
  const std::vector<frame_t> frame_of = keypoint_frames(map);
  std::vector<int64_t> subset;
  {
    std::vector<int64_t> pool = samples;
    rng.shuffle(pool);
    pool.resize(std::min<size_t>(pool.size(), static_cast<size_t>(naive_samples)));
    std::sort(pool.begin(), pool.end());
    subset = pool;
  }
  std::vector<uint8_t> row(static_cast<size_t>(layout.num_context_dims()));
  FrameContext context(regions, layout.num_words);
  double cpu = cpu_seconds();
  uint64_t checksum_naive = 0, checksum_fast = 0;
  for (size_t i = 0; i < subset.size(); ++i) {
    const frame_t f = frame_of[subset[i]];
    const FrameKeypoints frame = map_frame_keypoints(map, f, words);
    embed_context_brute_force(regions, layout.num_words, frame,
                              static_cast<int32_t>(subset[i] - map.frames[f].first_keypoint), row.data());
    for (uint8_t v : row) checksum_naive = checksum_naive * 31 + v;
  }
  const double naive_per_sample = (cpu_seconds() - cpu) / subset.size();
  cpu = cpu_seconds();
  for (size_t i = 0; i < subset.size(); ++i) {
    const frame_t f = frame_of[subset[i]];
    if (i == 0 || frame_of[subset[i - 1]] != f) context.reset(map_frame_keypoints(map, f, words));
    context.embed_context(static_cast<int32_t>(subset[i] - map.frames[f].first_keypoint), row.data());
    for (uint8_t v : row) checksum_fast = checksum_fast * 31 + v;
  }
  const double fast_subset_per_sample = (cpu_seconds() - cpu) / subset.size();
  LMB_CHECK(checksum_naive == checksum_fast, "context: fast and naive embeddings differ");
  return NaiveTimes{naive_per_sample, fast_subset_per_sample, subset.size()};
}

struct UsedDimsTimes {
  double query_us = 0, frame_us = 0, naive_us = 0;  // CPU microseconds per keypoint
  size_t dims = 0;
};

// Only a model's used dims (a.used_dims random ones) for every keypoint of a.used_dims_frames
// frames spread over the map, against the naive loop over the used regions (20 keypoints a frame).
UsedDimsTimes time_used_dims(const LandmarkMap& map, const ContextRegions& regions, const EmbeddingLayout& layout,
                             const std::vector<uint8_t>& words, const ContextBenchArgs& a, Rng& rng) {
  std::vector<int32_t> dims;
  {
    std::vector<int32_t> all(static_cast<size_t>(layout.num_dims()));
    for (int32_t d = 0; d < layout.num_dims(); ++d) all[d] = d;
    rng.shuffle(all);
    all.resize(std::min<size_t>(all.size(), static_cast<size_t>(a.used_dims)));
    std::sort(all.begin(), all.end());
    dims = all;
  }
  int32_t used_regions = 0;
  for (size_t i = 0; i < dims.size(); ++i) {
    if (layout.is_context(dims[i]) && (i == 0 || layout.region_of(dims[i]) != layout.region_of(dims[i - 1]))) {
      ++used_regions;
    }
  }
  const DimPlan plan(regions, layout, dims);
  FrameContext sparse_context(regions, layout.num_words);
  double prep_seconds = 0, reset_seconds = 0, query_seconds = 0, naive_seconds = 0;
  int64_t query_keypoints = 0, naive_keypoints = 0, max_frame_keypoints = 0;
  std::vector<uint8_t> out;
  std::vector<int32_t> counts(static_cast<size_t>(layout.num_words));
  uint64_t checksum_naive = 0;  // keeps the naive loop from being optimised away
  const int frames_to_use = std::min<int>(a.used_dims_frames, map.num_frames());
  for (int i = 0; i < frames_to_use; ++i) {
    const frame_t f = static_cast<frame_t>((static_cast<int64_t>(i) * map.num_frames()) / frames_to_use);
    const MapFrame& mf = map.frames[f];
    if (mf.num_keypoints == 0) continue;
    max_frame_keypoints = std::max<int64_t>(max_frame_keypoints, mf.num_keypoints);
    double cpu = cpu_seconds();
    const FrameKeypoints frame = map_frame_keypoints(map, f, words);
    prep_seconds += (cpu_seconds() - cpu);
    cpu = cpu_seconds();
    sparse_context.reset(frame);
    reset_seconds += (cpu_seconds() - cpu);
    out.resize(static_cast<size_t>(mf.num_keypoints) * dims.size());
    cpu = cpu_seconds();
    sparse_context.compute_dims_all(plan, map.descriptor(mf.first_keypoint), out.data());
    query_seconds += (cpu_seconds() - cpu);
    query_keypoints += mf.num_keypoints;
    // Naive: per keypoint, the regions x keypoints loop over the used regions only.
    const int32_t naive_k = std::min<int32_t>(mf.num_keypoints, 20);
    cpu = cpu_seconds();
    for (int32_t k = 0; k < naive_k; ++k) {
      for (size_t j = 0; j < dims.size(); ++j) {
        if (!layout.is_context(dims[j])) break;
        const int32_t r = layout.region_of(dims[j]);
        if (j > 0 && layout.region_of(dims[j - 1]) == r) continue;
        checksum_naive +=
            static_cast<uint64_t>(region_counts_brute_force(regions, layout.num_words, frame, k, r, counts.data()));
      }
    }
    naive_seconds += (cpu_seconds() - cpu);
    naive_keypoints += naive_k;
  }
  const double query_us = 1e6 * query_seconds / std::max<int64_t>(1, query_keypoints);
  const double frame_us = 1e6 * (prep_seconds + reset_seconds) / std::max<int64_t>(1, query_keypoints);
  const double naive_us = 1e6 * naive_seconds / std::max<int64_t>(1, naive_keypoints);
  spdlog::info(
      "bench context: {} used dims ({} regions): {:.1f} CPU-us/keypoint to compute them, "
      "plus {:.1f} us/keypoint for the frame (alignment {:.2f} ms + index {:.2f} ms per frame); "
      "naive {:.1f} us/keypoint: {:.1f}x (query only), {:.1f}x (with the frame)",
      dims.size(), used_regions, query_us, frame_us, 1e3 * prep_seconds / std::max(1, frames_to_use),
      1e3 * reset_seconds / std::max(1, frames_to_use), naive_us, naive_us / query_us,
      naive_us / (query_us + frame_us));
  if (checksum_naive == 1) spdlog::debug("bench context: checksum 1");
  return UsedDimsTimes{query_us, frame_us, naive_us, dims.size()};
}

void run_context_bench(const ContextBenchArgs& a) {
  check_outputs_not_inputs({{a.json_path, "--json"}}, {{a.map_path, "--map"}, {a.vocab_path, "--vocab"}});
  LMB_CHECK(!a.map_path.empty() || a.synthetic_frames > 0, "give --map map.h5 or --synthetic N");
  LMB_CHECK(a.map_path.empty() || a.synthetic_frames == 0, "--map and --synthetic exclude each other");
  LMB_CHECK(a.threads >= 1 && a.threads <= 256, "--threads " << a.threads << " must be in 1..256");
  LMB_CHECK(a.background_ratio >= 0, "--background-ratio must be >= 0");
  LMB_CHECK(a.naive_samples >= 1, "--naive-samples must be >= 1");
  LMB_CHECK(a.used_dims >= 1, "--used-dims must be >= 1");
  nlohmann::json report;
  const MachineInfo machine = machine_info();
  spdlog::info("bench context: machine {}", machine.summary());

  auto t = Clock::now();
  const LandmarkMap map = a.map_path.empty() ? synthetic_map(a) : read_map_h5(a.map_path);
  const std::string source =
      a.map_path.empty() ? "synthetic (" + std::to_string(a.synthetic_frames) + " frames)" : a.map_path;
  spdlog::info("bench context: map {}: {} frames, {} keypoints, {} landmarks, loaded in {:.1f} s", source,
               map.frames.size(), map.keypoints.size(), map.landmarks.size(), seconds_since(t));

  Vocabulary vocabulary;
  if (!a.vocab_path.empty()) {
    vocabulary = Vocabulary::load(a.vocab_path);
  } else {
    LMB_CHECK(a.synthetic_frames > 0, "--vocab is required with --map");
    // Synthetic only: 16 words trained on 20,000 of the map's random descriptors.
    const int64_t n = std::min<int64_t>(20000, static_cast<int64_t>(map.keypoints.size()));
    vocabulary = train_vocabulary(map.descriptors.data(), n, map.descriptor_bytes, VocabularyTrainOptions{});
  }
  ContextRegionOptions region_options;
  region_options.num_regions = a.regions;
  region_options.seed = a.region_seed;
  const ContextRegions regions(region_options);
  const EmbeddingLayout layout = embedding_layout(map, regions, vocabulary);
  spdlog::info("bench context: {} regions x {} words + {} bits = {} dims", layout.num_regions, layout.num_words,
               8 * layout.descriptor_bytes, layout.num_dims());

  // Samples: every map-frame keypoint with a landmark, plus background keypoints (no landmark)
  // drawn at random, background_ratio per landmark sample; in keypoint order.
  std::vector<int64_t> samples, background;
  for (const MapFrame& f : map.frames) {
    if (f.is_query) continue;
    for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
      (map.keypoint_landmark[k] != kInvalidLandmarkId ? samples : background).push_back(k);
    }
  }
  const int64_t positives = static_cast<int64_t>(samples.size());
  Rng rng(counter_hash(a.seed, 0x42454E43 /* "BENC" */));
  rng.shuffle(background);
  const int64_t num_background =
      std::min<int64_t>(static_cast<int64_t>(background.size()), std::llround(a.background_ratio * positives));
  samples.insert(samples.end(), background.begin(), background.begin() + num_background);
  std::sort(samples.begin(), samples.end());
  LMB_CHECK(!samples.empty(), "the map has no map-frame keypoints");

  // 1. All training feature vectors.
  FeatureBuildOptions build_options;
  build_options.num_threads = a.threads;
  t = Clock::now();
  double cpu = cpu_seconds();
  const FeatureMatrix features = build_training_features(map, regions, vocabulary, samples, build_options);
  const double build_seconds = seconds_since(t);
  const double build_cpu = cpu_seconds() - cpu;
  const double gib = static_cast<double>(features.data.size()) / (1024.0 * 1024.0 * 1024.0);
  spdlog::info(
      "bench context: built {} samples ({} with a landmark, {} background) x {} dims "
      "on {} threads in {:.2f} s wall, {:.2f} s CPU ({:.1f} CPU-us/sample); {:.2f} GiB "
      "uint8 ({} bytes/sample)",
      samples.size(), positives, num_background, layout.num_dims(), a.threads, build_seconds, build_cpu,
      1e6 * build_cpu / samples.size(), gib, layout.num_dims());

  // 2. Naive regions x keypoints loop on a subset, against the fast path on the same subset.
  const std::vector<uint8_t> words = keypoint_words(map, vocabulary, a.threads);
  const NaiveTimes naive = time_naive_and_fast(map, regions, layout, words, samples, a.naive_samples, rng);
  const double naive_per_sample = naive.naive_per_sample;
  const double fast_subset_per_sample = naive.fast_per_sample;
  const size_t subset_size = naive.samples;
  const double build_per_sample_thread = build_cpu / samples.size();
  spdlog::info(
      "bench context: naive loop {:.1f} CPU-us/sample ({} samples) -> all samples on {} "
      "threads ~{:.0f} s; fast path {:.1f} CPU-us/sample on the same subset (frame index "
      "built for each subset sample's frame), {:.1f} in the full build: {:.1f}x faster "
      "than naive",
      1e6 * naive_per_sample, subset_size, a.threads, naive_per_sample * samples.size() / a.threads,
      1e6 * fast_subset_per_sample, 1e6 * build_per_sample_thread, naive_per_sample / build_per_sample_thread);

  // 3. Only a model's used dims (random, sorted) for every keypoint of some frames.
  const UsedDimsTimes used = time_used_dims(map, regions, layout, words, a, rng);
  const double query_us = used.query_us, frame_us = used.frame_us, naive_us = used.naive_us;
  const size_t num_used_dims = used.dims;

  if (!a.json_path.empty()) {
    report["map"] = source;
    report["machine"] = {{"cpu_model", machine.cpu_model}, {"logical_cores", machine.logical_cores}};
    report["frames"] = map.frames.size();
    report["keypoints"] = map.keypoints.size();
    report["dims"] = layout.num_dims();
    report["threads"] = a.threads;
    report["samples"] = samples.size();
    report["samples_with_landmark"] = positives;
    report["build_seconds"] = build_seconds;
    report["build_cpu_seconds"] = build_cpu;
    report["feature_bytes"] = features.data.size();
    report["naive_us_per_sample"] = 1e6 * naive_per_sample;
    report["fast_us_per_sample_thread"] = 1e6 * build_per_sample_thread;
    report["speedup_vs_naive"] = naive_per_sample / build_per_sample_thread;
    report["used_dims"] = num_used_dims;
    report["used_dims_us_per_keypoint"] = query_us;
    report["used_dims_frame_us_per_keypoint"] = frame_us;
    report["used_dims_naive_us_per_keypoint"] = naive_us;
    write_file_atomically(a.json_path, report.dump(2) + "\n");
  }
}

}  // namespace

void add_context_bench(CLI::App& app) {
  auto args = std::make_shared<ContextBenchArgs>();
  auto* ctx = app.add_subcommand("context",
                                 "Time to build all training feature vectors (landmark keypoints + background) and to "
                                 "compute only a model's used dims, each against the naive regions x keypoints loop");
  ctx->add_option("--map", args->map_path, "map.h5");
  ctx->add_option("--vocab", args->vocab_path, "vocabulary (.lbv); optional with --synthetic");
  ctx->add_option("--synthetic", args->synthetic_frames, "instead of --map: this many random frames");
  ctx->add_option("--synthetic-keypoints", args->synthetic_keypoints, "keypoints per random frame")
      ->capture_default_str();
  ctx->add_option("--synthetic-landmark-fraction", args->synthetic_landmark_fraction,
                  "share of random keypoints observing a landmark")
      ->capture_default_str();
  ctx->add_option("--threads", args->threads, "threads for the full build")->capture_default_str();
  ctx->add_option("--regions", args->regions, "context regions")->capture_default_str();
  cli::add_seed_option(ctx, "--region-seed", &args->region_seed, "region set seed");
  ctx->add_option("--background-ratio", args->background_ratio, "background samples per landmark sample")
      ->capture_default_str();
  ctx->add_option("--used-dims", args->used_dims, "random dims a model would use")->capture_default_str();
  ctx->add_option("--naive-samples", args->naive_samples, "samples for the naive comparison")->capture_default_str();
  ctx->add_option("--used-dims-frames", args->used_dims_frames, "frames for the used-dims timing")
      ->capture_default_str();
  cli::add_seed_option(ctx, "--seed", &args->seed, "sampling seed");
  ctx->add_option("--json", args->json_path, "also write the figures as JSON");
  ctx->callback([args] { run_context_bench(*args); });
}

}  // namespace lmb::bench
