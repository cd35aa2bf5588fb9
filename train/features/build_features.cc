#include "train/features/build_features.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <new>
#include <numeric>
#include <string>
#include <thread>
#include <utility>

#include "common/error.h"
#include "common/hamming.h"

namespace lmb {

namespace {

constexpr int32_t kRowBlock = 256;  // samples per row block before transposing into columns
constexpr int32_t kTileDims = 64;   // dims per transpose tile

// Runs body(task, thread) for task in [0, num_tasks) on up to num_threads threads (dynamic
// scheduling); after a failure no new task starts, and the exception of the lowest failing task
// is rethrown once all threads stopped.
template <typename Body>
void parallel_tasks(int64_t num_tasks, int num_threads, Body body) {
  const int threads = static_cast<int>(std::max<int64_t>(1, std::min<int64_t>(num_threads, num_tasks)));
  std::atomic<int64_t> next{0};
  std::atomic<bool> failed{false};
  std::mutex mutex;
  std::exception_ptr first_error;
  int64_t first_error_task = -1;
  auto worker = [&](int thread) {
    for (;;) {
      if (failed.load(std::memory_order_relaxed)) return;
      const int64_t task = next.fetch_add(1);
      if (task >= num_tasks) return;
      try {
        body(task, thread);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex);
        if (first_error_task < 0 || task < first_error_task) {
          first_error = std::current_exception();
          first_error_task = task;
        }
        failed = true;
      }
    }
  };
  if (threads == 1) {
    worker(0);
  } else {
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t) pool.emplace_back(worker, t);
    for (auto& t : pool) t.join();
  }
  if (first_error) std::rethrow_exception(first_error);
}

std::string frame_name(const LandmarkMap& map, frame_t f) {
  return "frame " + std::to_string(f) + " (" + map.frames[f].name + ")";
}

}  // namespace

void FeatureBuildOptions::check(int32_t num_dims) const {
  LMB_CHECK(num_threads >= 1 && num_threads <= 256, "features: num_threads = " << num_threads << " must be in 1..256");
  for (size_t i = 0; i < dims.size(); ++i) {
    LMB_CHECK(dims[i] >= 0 && dims[i] < num_dims,
              "features: dims[" << i << "] = " << dims[i] << " is outside 0.." << num_dims - 1);
    LMB_CHECK(i == 0 || dims[i] > dims[i - 1],
              "features: dims must be sorted ascending without repeats (dims[" << i << "] = " << dims[i] << ")");
  }
  for (size_t i = 0; i < copies.size(); ++i) {
    LMB_CHECK(copies[i] >= 0, "features: copies[" << i << "] = " << copies[i] << " must be >= 0");
  }
  augment.check();
}

EmbeddingLayout embedding_layout(const LandmarkMap& map, const ContextRegions& regions, const Vocabulary& vocabulary) {
  vocabulary.check_descriptor_bytes(map.descriptor_bytes, "map descriptors");
  EmbeddingLayout layout{regions.size(), vocabulary.num_words(), map.descriptor_bytes};
  layout.check();
  return layout;
}

int64_t training_feature_bytes(int64_t num_samples, int64_t stored_dims, int num_threads, bool all_dims) {
  const int64_t threads = std::max(1, num_threads);
  // The matrix; per thread a row block; a plan keeps about 10 bytes a dim (its dims, words, offsets).
  return num_samples * stored_dims + threads * kRowBlock * stored_dims + (all_dims ? 0 : 10 * stored_dims);
}

std::vector<frame_t> keypoint_frames(const LandmarkMap& map) {
  const int64_t n = static_cast<int64_t>(map.keypoints.size());
  std::vector<frame_t> frames(static_cast<size_t>(n), kInvalidFrameId);
  for (frame_t f = 0; f < map.num_frames(); ++f) {
    const MapFrame& fr = map.frames[f];
    LMB_CHECK(fr.first_keypoint >= 0 && fr.num_keypoints >= 0 && fr.first_keypoint + fr.num_keypoints <= n,
              "map: " << frame_name(map, f) << " keypoints [" << fr.first_keypoint << ", "
                      << fr.first_keypoint + fr.num_keypoints << ") exceed the " << n << " keypoints");
    for (int64_t k = fr.first_keypoint; k < fr.first_keypoint + fr.num_keypoints; ++k) {
      LMB_CHECK(frames[k] == kInvalidFrameId,
                "map: keypoint " << k << " belongs to two frames (" << frames[k] << " and " << f << ")");
      frames[k] = f;
    }
  }
  return frames;
}

std::vector<uint8_t> keypoint_words(const LandmarkMap& map, const Vocabulary& vocabulary, int num_threads) {
  vocabulary.check_descriptor_bytes(map.descriptor_bytes, "map descriptors");
  const int64_t n = static_cast<int64_t>(map.keypoints.size());
  LMB_CHECK(static_cast<int64_t>(map.descriptors.size()) == n * map.descriptor_bytes,
            "map: " << map.descriptors.size() << " descriptor bytes for " << n << " keypoints of "
                    << map.descriptor_bytes << " bytes");
  std::vector<uint8_t> words(static_cast<size_t>(n));
  constexpr int64_t kChunk = 1 << 14;
  const int64_t chunks = (n + kChunk - 1) / kChunk;
  parallel_tasks(chunks, num_threads, [&](int64_t c, int) {
    const int64_t begin = c * kChunk, end = std::min(n, begin + kChunk);
    vocabulary.quantize(map.descriptor(begin), end - begin, words.data() + begin);
  });
  return words;
}

FrameKeypoints map_frame_keypoints(const LandmarkMap& map, frame_t f, const std::vector<uint8_t>& words) {
  LMB_CHECK(f >= 0 && f < map.num_frames(), "map: frame " << f << " out of range");
  const MapFrame& fr = map.frames[f];
  LMB_CHECK(fr.camera >= 0 && fr.camera < static_cast<camera_t>(map.cameras.size()),
            "map: " << frame_name(map, f) << " camera " << fr.camera << " out of range");
  LMB_CHECK(fr.first_keypoint >= 0 && fr.num_keypoints >= 0 &&
                fr.first_keypoint + fr.num_keypoints <= static_cast<int64_t>(words.size()) &&
                fr.first_keypoint + fr.num_keypoints <= static_cast<int64_t>(map.keypoints.size()),
            "map: " << frame_name(map, f) << " keypoint range out of bounds");
  return frame_keypoints_from_detections(map.cameras[fr.camera], map.keypoints.data() + fr.first_keypoint,
                                         words.data() + fr.first_keypoint, fr.num_keypoints, fr.gravity_in_cam,
                                         "map: " + frame_name(map, f));
}

FeatureMatrix build_training_features(const LandmarkMap& map, const ContextRegions& regions,
                                      const Vocabulary& vocabulary, const std::vector<int64_t>& sample_keypoints,
                                      const FeatureBuildOptions& options) {
  const EmbeddingLayout layout = embedding_layout(map, regions, vocabulary);
  options.check(layout.num_dims());
  const int64_t num_keypoints = static_cast<int64_t>(map.keypoints.size());
  const int64_t num_samples = static_cast<int64_t>(sample_keypoints.size());
  for (int64_t i = 0; i < num_samples; ++i) {
    LMB_CHECK(
        sample_keypoints[i] >= 0 && sample_keypoints[i] < num_keypoints,
        "features: sample " << i << " keypoint " << sample_keypoints[i] << " is outside 0.." << num_keypoints - 1);
  }
  const bool augmented = !options.copies.empty();
  LMB_CHECK(!augmented || static_cast<int64_t>(options.copies.size()) == num_samples,
            "features: " << options.copies.size() << " copies for " << num_samples << " samples");
  auto copy_of = [&](int64_t i) { return augmented ? options.copies[i] : 0; };
  for (int64_t i = 0; augmented && i < num_samples; ++i) {
    LMB_CHECK(
        options.copies[i] == 0 || augmented_keypoint_kept(options.augment, sample_keypoints[i], options.copies[i]),
        "features: sample " << i << " is copy " << options.copies[i] << " of keypoint " << sample_keypoints[i]
                            << ", which that copy drops");
  }
  const std::vector<frame_t> frame_of = keypoint_frames(map);
  for (int64_t i = 0; i < num_samples; ++i) {
    LMB_CHECK(frame_of[sample_keypoints[i]] != kInvalidFrameId,
              "features: sample keypoint " << sample_keypoints[i] << " belongs to no frame");
  }
  const std::vector<uint8_t> words = keypoint_words(map, vocabulary, options.num_threads);

  const bool all_dims = options.dims.empty();
  const int32_t stored = all_dims ? layout.num_dims() : static_cast<int32_t>(options.dims.size());
  FeatureMatrix m;
  m.num_samples = num_samples;
  m.num_dims = layout.num_dims();
  m.dims = options.dims;
  try {
    m.data.resize(static_cast<size_t>(num_samples) * stored);
  } catch (const std::bad_alloc&) {
    LMB_FAIL("features: out of memory for the feature matrix of " << num_samples << " samples x " << stored << " dims ("
                                                                  << num_samples * stored << " bytes)");
  }

  // Samples grouped by (frame, copy): order[] sorted by (frame, copy, sample index); one task per group.
  std::vector<int64_t> order(static_cast<size_t>(num_samples));
  std::iota(order.begin(), order.end(), 0);
  auto group_of = [&](int64_t i) { return std::pair{frame_of[sample_keypoints[i]], copy_of(i)}; };
  std::stable_sort(order.begin(), order.end(), [&](int64_t a, int64_t b) { return group_of(a) < group_of(b); });
  std::vector<int64_t> task_begin;
  for (int64_t i = 0; i < num_samples; ++i) {
    if (i == 0 || group_of(order[i]) != group_of(order[i - 1])) task_begin.push_back(i);
  }
  const int64_t num_tasks = static_cast<int64_t>(task_begin.size());
  task_begin.push_back(num_samples);

  const int threads = static_cast<int>(std::max<int64_t>(1, std::min<int64_t>(options.num_threads, num_tasks)));
  struct ThreadState {
    FrameContext context;
    std::vector<uint8_t> rows;
    std::vector<int32_t> index_in_copy;
  };
  std::vector<ThreadState> states;
  DimPlan plan;
  try {
    states.reserve(static_cast<size_t>(threads));
    for (int t = 0; t < threads; ++t) {
      states.push_back(
          {FrameContext(regions, layout.num_words), std::vector<uint8_t>(static_cast<size_t>(kRowBlock) * stored), {}});
    }
    if (!all_dims) plan = DimPlan(regions, layout, options.dims);
  } catch (const std::bad_alloc&) {
    LMB_FAIL("features: out of memory for the row blocks of " << threads << " threads x " << kRowBlock << " samples x "
                                                              << stored << " dims");
  }
  const int32_t context_dims = layout.num_context_dims();
  const int32_t bytes = layout.descriptor_bytes;

  parallel_tasks(num_tasks, threads, [&](int64_t task, int thread) {
    ThreadState& st = states[thread];
    const frame_t f = frame_of[sample_keypoints[order[task_begin[task]]]];
    const int32_t copy = copy_of(order[task_begin[task]]);
    const int64_t first = map.frames[f].first_keypoint;
    if (copy == 0) {
      st.context.reset(map_frame_keypoints(map, f, words), "map: " + frame_name(map, f));
    } else {
      st.context.reset(
          augmented_frame(map_frame_keypoints(map, f, words), f, first, options.augment, copy, &st.index_in_copy),
          "map: " + frame_name(map, f) + " copy " + std::to_string(copy));
    }
    for (int64_t b = task_begin[task]; b < task_begin[task + 1]; b += kRowBlock) {
      const int32_t block = static_cast<int32_t>(std::min<int64_t>(kRowBlock, task_begin[task + 1] - b));
      for (int32_t j = 0; j < block; ++j) {
        const int64_t keypoint = sample_keypoints[order[b + j]];
        const int32_t k = copy == 0 ? static_cast<int32_t>(keypoint - first)
                                    : st.index_in_copy[static_cast<size_t>(keypoint - first)];
        uint8_t* row = st.rows.data() + static_cast<size_t>(j) * stored;
        const uint8_t* descriptor = map.descriptor(keypoint);
        if (all_dims) {
          st.context.embed_context(k, row);
          uint8_t* bits = row + context_dims;
          for (int32_t byte = 0; byte < bytes; ++byte) {
            const unsigned v = descriptor[byte];  // LSB first, as lmb::descriptor_bit
            for (int32_t i = 0; i < 8; ++i) bits[8 * byte + i] = static_cast<uint8_t>((v >> i) & 1u);
          }
        } else {
          st.context.compute_dims(k, plan, descriptor, row);
        }
      }
      // Transpose the row block into the columns, a tile of dims at a time.
      for (int32_t d0 = 0; d0 < stored; d0 += kTileDims) {
        const int32_t tile = std::min(stored - d0, kTileDims);
        uint8_t* columns = m.column(d0);
        for (int32_t j = 0; j < block; ++j) {
          const uint8_t* src = st.rows.data() + static_cast<size_t>(j) * stored + d0;
          uint8_t* dst = columns + order[b + j];
          for (int32_t d = 0; d < tile; ++d) dst[d * num_samples] = src[d];
        }
      }
    }
  });
  return m;
}

}  // namespace lmb
