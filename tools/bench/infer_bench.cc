// `lboost-bench infer`: single-thread inference timings (context embedding, classification dense
// and with the inverted file, pose) against OpenCV's BFMatcher (Hamming 1-NN and 2-NN over every
// training descriptor) and a plain popcount 1-NN loop, all measured in the same run.
//
// Model: --model model.lbm, or --synthetic-paper (train/export/synthetic_model.h: a random model
// of the paper's shape, 7,500 classes x 2,000 stumps over 16,512 dims; --classes / --stumps scale
// it down). Frames and training descriptors: a map's query frames and map-frame landmark
// observations (--map), or synthetic ones (--frames random frames of --keypoints keypoints with
// random descriptors, --train-descriptors random training descriptors; the paper world's map has
// ~400k landmark observations).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>

#include "common/context_embedding.h"
#include "common/error.h"
#include "common/file_io.h"
#include "common/hamming.h"
#include "common/io/map_h5.h"
#include "common/machine_info.h"
#include "common/random.h"
#include "common/simd/simd_level.h"
#include "infer/classifier.h"
#include "infer/detail/scoring_index.h"
#include "infer/localizer.h"
#include "infer/model.h"
#include "infer/pose_estimator.h"
#include "tools/bench/bench_commands.h"
#include "train/cli/cli_util.h"
#include "train/eval/timing.h"
#include "train/export/synthetic_model.h"

namespace lmb::bench {

namespace {

struct BenchInferArgs {
  std::string model;
  bool synthetic_paper = false;
  SyntheticModelOptions synthetic;
  std::string map;
  int keypoints = 1000;  // per frame: the first N of each query frame (all when fewer)
  int repeats = 3;
  int max_frames = 0;              // 0 = every query frame (map) / number of synthetic frames
  int frames = 5;                  // synthetic frames (without --map)
  int train_descriptors = 400000;  // synthetic training descriptors (without --map)
  int ransac_iterations = 500;
  int inverted_file_words = 1;  // the inverted-file rows: words a keypoint
  bool popcount = true;
  std::string json;
};

struct BenchFrame {
  Camera camera;
  std::vector<Keypoint> keypoints;
  std::vector<uint8_t> descriptors;
  Eigen::Vector3d gravity_in_cam;
};

struct Sums {
  double embedding = 0, classification = 0, pose = 0, total = 0, cpu = 0;
};

// Random frames: keypoints uniform over a 752 x 480 pinhole image, BRISK-like diameters
// (log-uniform 12..48 px), random descriptors, gravity along the image's +y.
std::vector<BenchFrame> synthetic_frames(int num_frames, int keypoints, int bytes, uint64_t seed) {
  Rng rng(seed);
  std::vector<BenchFrame> frames(static_cast<size_t>(num_frames));
  for (BenchFrame& f : frames) {
    f.camera.model = CameraModel::kPinhole;
    f.camera.width = 752;
    f.camera.height = 480;
    f.camera.params = {450.0, 450.0, 376.0, 240.0};
    f.gravity_in_cam = Eigen::Vector3d(0.0, 1.0, 0.0);
    for (int k = 0; k < keypoints; ++k) {
      Keypoint kp;
      kp.x = static_cast<float>(rng.uniform(0.0, 752.0));
      kp.y = static_cast<float>(rng.uniform(0.0, 480.0));
      kp.scale = static_cast<float>(12.0 * std::exp(rng.uniform(0.0, std::log(4.0))));
      kp.angle = static_cast<float>(rng.uniform(0.0, 360.0));
      f.keypoints.push_back(kp);
    }
    f.descriptors.resize(static_cast<size_t>(keypoints) * bytes);
    for (uint8_t& b : f.descriptors) b = static_cast<uint8_t>(rng.below(256));
  }
  return frames;
}

// The model under test: --model, or the synthetic paper-shape model.
std::shared_ptr<const Model> load_bench_model(const BenchInferArgs& a, double* load_ms) {
  const Clock::time_point t_load = Clock::now();
  std::shared_ptr<const Model> model;
  if (a.synthetic_paper) {
    SyntheticModelStats stats;
    model = std::make_shared<const Model>(make_synthetic_model(a.synthetic, &stats));
  } else {
    model = Model::load(a.model);
  }
  *load_ms = ms_since(t_load);
  return model;
}

// The frames and the baselines' training descriptors.
struct BenchData {
  std::vector<BenchFrame> frames;
  std::vector<uint8_t> train;  // training descriptors, flat rows
  int num_train = 0;
};

// A map's query frames (the first --keypoints of each) and every map-frame landmark observation.
BenchData map_bench_data(const BenchInferArgs& a, int bytes) {
  BenchData d;
  const LandmarkMap map = read_map_h5(a.map);
  LMB_CHECK(map.descriptor_bytes == bytes, a.map << ": descriptor length differs from the model's");
  for (const MapFrame& f : map.frames) {
    if (f.is_query) continue;
    for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
      if (map.keypoint_landmark[k] >= 0) d.train.insert(d.train.end(), map.descriptor(k), map.descriptor(k) + bytes);
    }
  }
  for (const MapFrame& mf : map.frames) {
    if (!mf.is_query) continue;
    if (a.max_frames > 0 && static_cast<int>(d.frames.size()) >= a.max_frames) break;
    const int n = std::min(a.keypoints, mf.num_keypoints);
    BenchFrame f;
    f.camera = map.cameras[mf.camera];
    f.gravity_in_cam = mf.gravity_in_cam;
    f.keypoints.assign(map.keypoints.begin() + mf.first_keypoint, map.keypoints.begin() + mf.first_keypoint + n);
    f.descriptors.assign(map.descriptor(mf.first_keypoint),
                         map.descriptor(mf.first_keypoint) + static_cast<int64_t>(n) * bytes);
    d.frames.push_back(std::move(f));
  }
  LMB_CHECK(!d.frames.empty(), a.map << ": no query frames");
  return d;
}

BenchData load_bench_data(const BenchInferArgs& a, int bytes) {
  BenchData d;
  if (!a.map.empty()) {
    d = map_bench_data(a, bytes);
  } else {
    LMB_CHECK(a.frames >= 1 && a.train_descriptors >= 1, "--frames and --train-descriptors must be >= 1");
    d.frames = synthetic_frames(a.max_frames > 0 ? std::min(a.frames, a.max_frames) : a.frames, a.keypoints, bytes,
                                a.synthetic.seed + 1);
    Rng rng(a.synthetic.seed + 2);
    d.train.resize(static_cast<size_t>(a.train_descriptors) * bytes);
    for (uint8_t& b : d.train) b = static_cast<uint8_t>(rng.below(256));
  }
  d.num_train = static_cast<int>(d.train.size() / bytes);
  LMB_CHECK(d.num_train > 0, "no training descriptors");
  return d;
}

// OpenCV's BFMatcher takes at most 2^18 rows per training image: the descriptors go in as a
// collection of chunks (matched all at once by match / knnMatch).
void train_bfmatcher(cv::BFMatcher& bf, BenchData& d, int bytes) {
  constexpr int kChunk = 1 << 17;
  std::vector<cv::Mat> chunks;
  for (int first = 0; first < d.num_train; first += kChunk) {
    chunks.emplace_back(std::min(kChunk, d.num_train - first), bytes, CV_8U,
                        d.train.data() + static_cast<int64_t>(first) * bytes);
  }
  bf.add(chunks);
  bf.train();
}

// The end-to-end pass: each frame localized dense and with the inverted file, and matched by the
// BFMatcher (1-NN, 2-NN) and the popcount loop.
struct EndToEnd {
  Sums dense, inverted;
  double bf_ms = 0, bf_knn_ms = 0, popcount_ms = 0, bf_cpu_ms = 0;
  int64_t keypoints_total = 0, correspondences = 0, inliers = 0;
  int runs = 0;
};

void add_localization(const LocalizeResult& r, double cpu_ms, Sums& s) {
  s.cpu += cpu_ms;
  s.embedding += r.timings.embedding_ms + r.timings.words_ms;
  s.classification += r.timings.classification_ms;
  s.pose += r.timings.pose_ms;
  s.total += r.timings.total_ms;
}

// The popcount 1-NN loop over every training descriptor; returns a checksum of the distances.
int64_t popcount_1nn(const uint8_t* desc, int n, const BenchData& d, int bytes) {
  int64_t checksum = 0;
  for (int q = 0; q < n; ++q) {
    int best = 1 << 30;
    for (int j = 0; j < d.num_train; ++j) {
      best = std::min(best, hamming_distance(desc + static_cast<int64_t>(q) * bytes,
                                             d.train.data() + static_cast<int64_t>(j) * bytes, bytes));
    }
    checksum += best;
  }
  return checksum;
}

EndToEnd time_end_to_end(const BenchInferArgs& a, const BenchData& d, const Localizer& dense, const Localizer& inverted,
                         cv::BFMatcher& bf, int bytes, int64_t& checksum) {
  EndToEnd e;
  for (int rep = 0; rep < a.repeats; ++rep) {
    for (const BenchFrame& f : d.frames) {
      const int n = static_cast<int>(f.keypoints.size());
      const uint8_t* desc = f.descriptors.data();
      for (int mode = 0; mode < 2; ++mode) {
        const double cpu0 = thread_cpu_ms();
        const LocalizeResult r = (mode ? inverted : dense).localize(f.camera, f.keypoints, desc, f.gravity_in_cam);
        add_localization(r, thread_cpu_ms() - cpu0, mode ? e.inverted : e.dense);
        if (mode) {
          e.correspondences += static_cast<int64_t>(r.correspondence_keypoint.size());
          e.inliers += r.pose.num_inliers;
        }
      }
      const cv::Mat query(n, bytes, CV_8U, const_cast<uint8_t*>(desc));
      std::vector<cv::DMatch> matches;
      Clock::time_point t = Clock::now();
      const double cpu0 = thread_cpu_ms();
      bf.match(query, matches);
      e.bf_cpu_ms += thread_cpu_ms() - cpu0;
      e.bf_ms += ms_since(t);
      std::vector<std::vector<cv::DMatch>> knn;
      t = Clock::now();
      bf.knnMatch(query, knn, 2);
      e.bf_knn_ms += ms_since(t);
      checksum += static_cast<int64_t>(matches.size() + knn.size());
      if (a.popcount) {
        t = Clock::now();
        checksum += popcount_1nn(desc, n, d, bytes);
        e.popcount_ms += ms_since(t);
      }
      e.keypoints_total += n;
      ++e.runs;
    }
  }
  return e;
}

// Thread CPU of each stage with the inverted file (the localizer's timings are wall clock, which
// a busy machine inflates): each stage run on its own, frame by frame. Embedding = descriptor
// quantization, keypoint normalization, and classify()'s own frame index and dims (its
// embedding_ms: one thread, so wall = CPU but for preemption); scoring = the rest of classify();
// pose = estimate_absolute_pose on the localizer's correspondences. Also the scoring without
// screening (ClassifierOptions::screening = false), for the ratio.
struct StageCpu {
  double embedding = 0, scoring = 0, pose = 0, unscreened = 0;
  double scored_share = 0;  // candidate classes scored exactly / screened
  // Dense scoring (classify() less its embedding), with and without the fusion balls.
  double dense_scoring = 0, dense_without_balls = 0;
};

// Thread CPU of classify() less its own embedding time.
double scoring_cpu_ms(Classifier& classifier, const FrameKeypoints& fk, const uint8_t* desc, int64_t& checksum) {
  double embedding_ms = 0;
  const double t0 = thread_cpu_ms();
  checksum += static_cast<int64_t>(classifier.classify(fk, desc, "bench", &embedding_ms).matches.size());
  return thread_cpu_ms() - t0 - embedding_ms;
}

StageCpu time_stages(const BenchInferArgs& a, const std::shared_ptr<const Model>& model, const BenchData& d,
                     const Localizer& inverted, int64_t& checksum) {
  const LocalizerOptions& options = inverted.options();
  StageCpu s;
  Classifier classifier(model, options.classifier);
  ClassifierOptions unscreened_options = options.classifier;
  unscreened_options.screening = false;
  Classifier unscreened(model, unscreened_options);
  ClassifierOptions dense_options = options.classifier;
  dense_options.use_inverted_file = false;
  Classifier dense(model, dense_options);
  dense_options.fusion_balls = false;
  Classifier dense_without_balls(model, dense_options);
  for (int rep = 0; rep < a.repeats; ++rep) {
    for (const BenchFrame& f : d.frames) {
      const int n = static_cast<int>(f.keypoints.size());
      const uint8_t* desc = f.descriptors.data();
      const LocalizeResult r = inverted.localize(f.camera, f.keypoints, desc, f.gravity_in_cam);
      const double t0 = thread_cpu_ms();
      std::vector<uint8_t> words(static_cast<size_t>(n));
      model->vocabulary().quantize(desc, n, words.data());
      const FrameKeypoints fk =
          frame_keypoints_from_detections(f.camera, f.keypoints.data(), words.data(), n, f.gravity_in_cam, "bench");
      const double t1 = thread_cpu_ms();
      double embedding_ms = 0;
      checksum += static_cast<int64_t>(classifier.classify(fk, desc, "bench", &embedding_ms).matches.size());
      const double t3 = thread_cpu_ms();
      s.unscreened += scoring_cpu_ms(unscreened, fk, desc, checksum);
      s.dense_scoring += scoring_cpu_ms(dense, fk, desc, checksum);
      s.dense_without_balls += scoring_cpu_ms(dense_without_balls, fk, desc, checksum);
      std::vector<Eigen::Vector2d> pixels;
      std::vector<Eigen::Vector3d> points;
      for (size_t i = 0; i < r.correspondence_keypoint.size(); ++i) {
        const Keypoint& kp = f.keypoints[r.correspondence_keypoint[i]];
        pixels.emplace_back(kp.x, kp.y);
        points.push_back(model->class_position(r.matches.matches[r.correspondence_match[i]].cls));
      }
      const double t4 = thread_cpu_ms();
      checksum += estimate_absolute_pose(f.camera, pixels, points, options.pose).num_inliers;
      const double t5 = thread_cpu_ms();
      s.embedding += (t1 - t0) + embedding_ms;
      s.scoring += (t3 - t1) - embedding_ms;
      s.pose += t5 - t4;
    }
  }
  s.scored_share = static_cast<double>(classifier.classes_scored()) /
                   static_cast<double>(std::max<int64_t>(1, classifier.classes_screened()));
  return s;
}

// The unbatched path (one keypoint at a time: Classifier::dense_scores, and class_score over the
// word's candidates), on the first frame, for the speed-up of the batched classify().
struct Unbatched {
  double dense_ms = 0, inverted_ms = 0;
};

Unbatched time_unbatched(const std::shared_ptr<const Model>& model, const BenchFrame& f, int bytes, int64_t& checksum) {
  Unbatched u;
  const int n = static_cast<int>(f.keypoints.size());
  std::vector<uint8_t> words(static_cast<size_t>(n));
  model->vocabulary().quantize(f.descriptors.data(), n, words.data());
  const FrameKeypoints fk =
      frame_keypoints_from_detections(f.camera, f.keypoints.data(), words.data(), n, f.gravity_in_cam, "bench");
  Classifier c(model);
  c.index_frame(fk);
  std::vector<uint8_t> values(model->scoring().used_dims().size());
  std::vector<double> scores(static_cast<size_t>(model->num_classes()) + 1);
  double sink = 0;
  for (int k = 0; k < n; ++k) {
    c.compute_used_values(k, f.descriptors.data() + static_cast<int64_t>(k) * bytes, values.data());
    Clock::time_point t = Clock::now();
    c.dense_scores(values.data(), scores.data());
    sink += scores[0];
    u.dense_ms += ms_since(t);
    t = Clock::now();
    const int32_t w = fk.word[k];
    for (int32_t i = model->scoring().word_class_begin()[w]; i < model->scoring().word_class_begin()[w + 1]; ++i) {
      sink += c.class_score(values.data(), model->scoring().word_classes()[i]);
    }
    sink += c.class_score(values.data(), model->background_class());
    u.inverted_ms += ms_since(t);
  }
  checksum += static_cast<int64_t>(sink) & 1;
  return u;
}

// Everything measured, for the printout and the JSON.
struct BenchFigures {
  double load_ms = 0;
  size_t frames = 0;
  int num_train = 0;
  EndToEnd e;
  StageCpu stages;
  Unbatched unbatched;
  int64_t checksum = 0;
};

void print_bench(const BenchInferArgs& a, const Model& m, const BenchFigures& b) {
  const double nr = b.e.runs;
  const Sums& sd = b.e.dense;
  const Sums& si = b.e.inverted;
  const double kp_per_frame = static_cast<double>(b.e.keypoints_total) / nr;
  const double match_dense = (sd.embedding + sd.classification) / nr;
  const double match_inverted = (si.embedding + si.classification) / nr;
  const double bf = b.e.bf_ms / nr;
  std::printf(
      "bench infer: %s model: %d classes, %zu stumps, %lld sharing entries, %zu used dims, %lld inverted-file "
      "entries (built/loaded in %.0f ms)\n",
      a.synthetic_paper ? "synthetic" : "trained", m.num_classes(), m.data().stumps.size(),
      static_cast<long long>(m.scoring().stump_classes().size()), m.scoring().used_dims().size(),
      static_cast<long long>(m.scoring().word_classes().size()), b.load_ms);
  std::printf("  machine: %s; SIMD level %s (LMB_SIMD caps it)\n", machine_info().summary().c_str(),
              simd_level_name(simd_level()));
  std::printf(
      "  %zu %s frames x %d repeats, %.0f keypoints a frame; %d training descriptors; 1 thread; %d RANSAC iterations\n",
      b.frames, a.map.empty() ? "synthetic" : "query", a.repeats, kp_per_frame, b.num_train, a.ransac_iterations);
  std::printf("  dense:         embedding %.2f ms, classification %.2f ms, pose %.2f ms, total %.2f ms a frame\n",
              sd.embedding / nr, sd.classification / nr, sd.pose / nr, sd.total / nr);
  std::printf(
      "  inverted file%s: embedding %.2f ms, classification %.2f ms, pose %.2f ms, total %.2f ms a frame "
      "(%.0f correspondences, %.1f inliers)\n",
      a.inverted_file_words > 1 ? (" (" + std::to_string(a.inverted_file_words) + " words a keypoint)").c_str() : "",
      si.embedding / nr, si.classification / nr, si.pose / nr, si.total / nr, b.e.correspondences / nr,
      b.e.inliers / nr);
  std::printf(
      "  unbatched scoring (one keypoint at a time, first frame): dense %.2f ms, inverted file %.2f ms a frame\n",
      b.unbatched.dense_ms, b.unbatched.inverted_ms);
  std::printf("  OpenCV BFMatcher (Hamming): 1-NN %.2f ms, 2-NN %.2f ms a frame; popcount 1-NN loop: %.2f ms a frame\n",
              bf, b.e.bf_knn_ms / nr, b.e.popcount_ms / nr);
  std::printf(
      "  thread CPU time a frame: localization dense %.2f ms, inverted file %.2f ms; BFMatcher 1-NN %.2f ms "
      "(inverted-file localization / BFMatcher 1-NN: 1/%.1f)\n",
      sd.cpu / nr, si.cpu / nr, b.e.bf_cpu_ms / nr, b.e.bf_cpu_ms / si.cpu);
  std::printf(
      "  thread CPU time a frame by stage, inverted file (each stage run on its own): embedding %.2f ms, "
      "scoring %.2f ms, pose %.2f ms\n",
      b.stages.embedding / nr, b.stages.scoring / nr, b.stages.pose / nr);
  std::printf(
      "  screening: %.2f%% of the candidate classes scored exactly; scoring without screening %.2f ms "
      "(%.1fx)\n",
      100.0 * b.stages.scored_share, b.stages.unscreened / nr, b.stages.unscreened / b.stages.scoring);
  if (m.has_fusion()) {
    std::printf("  dense scoring with the fusion balls %.2f ms, without them %.2f ms (%.1fx)\n",
                b.stages.dense_scoring / nr, b.stages.dense_without_balls / nr,
                b.stages.dense_without_balls / b.stages.dense_scoring);
  }
  std::printf(
      "  matching (embedding + classification) / BFMatcher 1-NN: dense %.4f (1/%.1f), inverted file %.4f "
      "(1/%.1f) (checksum %lld)\n",
      match_dense / bf, bf / match_dense, match_inverted / bf, bf / match_inverted, static_cast<long long>(b.checksum));
}

nlohmann::json bench_json(const BenchInferArgs& a, const Model& m, const BenchFigures& b) {
  const double nr = b.e.runs;
  const Sums& sd = b.e.dense;
  const Sums& si = b.e.inverted;
  const double bf = b.e.bf_ms / nr;
  return {{"model", a.synthetic_paper ? "synthetic" : a.model},
          {"machine", machine_info().summary()},
          {"simd_level", simd_level_name(simd_level())},
          {"classes", m.num_classes()},
          {"stumps", m.data().stumps.size()},
          {"sharing_entries", m.scoring().stump_classes().size()},
          {"used_dims", m.scoring().used_dims().size()},
          {"inverted_file_entries", m.scoring().word_classes().size()},
          {"frames", b.frames},
          {"repeats", a.repeats},
          {"keypoints_per_frame", static_cast<double>(b.e.keypoints_total) / nr},
          {"training_descriptors", b.num_train},
          {"ransac_iterations", a.ransac_iterations},
          {"inverted_file_words", a.inverted_file_words},
          {"dense_ms",
           {{"embedding", sd.embedding / nr},
            {"classification", sd.classification / nr},
            {"pose", sd.pose / nr},
            {"total", sd.total / nr}}},
          {"inverted_file_ms",
           {{"embedding", si.embedding / nr},
            {"classification", si.classification / nr},
            {"pose", si.pose / nr},
            {"total", si.total / nr}}},
          {"cpu_ms",
           {{"dense_localization", sd.cpu / nr},
            {"inverted_file_localization", si.cpu / nr},
            {"bfmatcher", b.e.bf_cpu_ms / nr},
            {"inverted_file_stages",
             {{"embedding", b.stages.embedding / nr},
              {"scoring", b.stages.scoring / nr},
              {"pose", b.stages.pose / nr},
              {"scoring_unscreened", b.stages.unscreened / nr}}},
            {"dense_scoring", b.stages.dense_scoring / nr},
            {"dense_scoring_without_fusion_balls", b.stages.dense_without_balls / nr}}},
          {"screening_scored_share", b.stages.scored_share},
          {"unbatched_scoring_ms", {{"dense", b.unbatched.dense_ms}, {"inverted_file", b.unbatched.inverted_ms}}},
          {"bfmatcher_ms", bf},
          {"bfmatcher_knn2_ms", b.e.bf_knn_ms / nr},
          {"popcount_ms", b.e.popcount_ms / nr},
          {"match_ratio_dense", (sd.embedding + sd.classification) / nr / bf},
          {"match_ratio_inverted_file", (si.embedding + si.classification) / nr / bf}};
}

void run_bench_infer(const BenchInferArgs& a) {
  check_outputs_not_inputs({{a.json, "--json"}}, {{a.model, "--model"}, {a.map, "--map"}});
  LMB_CHECK(a.keypoints >= 1 && a.repeats >= 1, "--keypoints and --repeats must be >= 1");
  LMB_CHECK(a.synthetic_paper != !a.model.empty(), "give exactly one of --model and --synthetic-paper");
  BenchFigures b;
  const std::shared_ptr<const Model> model = load_bench_model(a, &b.load_ms);
  const int bytes = model->descriptor_bytes();
  BenchData d = load_bench_data(a, bytes);
  b.frames = d.frames.size();
  b.num_train = d.num_train;
  cv::BFMatcher bf(cv::NORM_HAMMING, false);
  train_bfmatcher(bf, d, bytes);

  LocalizerOptions dense_options;
  dense_options.pose.max_iterations = a.ransac_iterations;
  LocalizerOptions inverted_options = dense_options;
  inverted_options.classifier.use_inverted_file = true;
  inverted_options.classifier.inverted_file_words = a.inverted_file_words;
  const Localizer dense(model, dense_options), inverted(model, inverted_options);
  b.e = time_end_to_end(a, d, dense, inverted, bf, bytes, b.checksum);
  b.stages = time_stages(a, model, d, inverted, b.checksum);
  b.unbatched = time_unbatched(model, d.frames.front(), bytes, b.checksum);
  print_bench(a, *model, b);
  if (!a.json.empty()) write_file_atomically(a.json, bench_json(a, *model, b).dump(1) + "\n");
}

}  // namespace

void add_infer_bench(CLI::App& app) {
  auto args = std::make_shared<BenchInferArgs>();
  auto* cmd = app.add_subcommand(
      "infer", "Inference timings (embedding, classification dense / inverted file, pose) vs OpenCV BFMatcher");
  cmd->add_option("--model", args->model, "Inference model (model.lbm)");
  cmd->add_flag("--synthetic-paper", args->synthetic_paper,
                "Instead of --model: a random model of the paper's shape (7,500 classes, 2,000 stumps)");
  cmd->add_option("--classes", args->synthetic.num_classes, "Synthetic model: classes")->capture_default_str();
  cmd->add_option("--stumps", args->synthetic.num_stumps, "Synthetic model: stumps")->capture_default_str();
  cli::add_seed_option(cmd, "--seed", &args->synthetic.seed, "Synthetic model and frames: seed");
  cmd->add_option("--map", args->map,
                  "Map whose query frames and training observations are used (map.h5); "
                  "default: synthetic frames and descriptors");
  cmd->add_option("--keypoints", args->keypoints, "Keypoints a frame (the first N)")->capture_default_str();
  cmd->add_option("--repeats", args->repeats, "Passes over the frames")->capture_default_str();
  cmd->add_option("--max-frames", args->max_frames, "At most this many query frames (0 = all)")->capture_default_str();
  cmd->add_option("--frames", args->frames, "Synthetic frames (without --map)")->capture_default_str();
  cmd->add_option("--train-descriptors", args->train_descriptors,
                  "Synthetic training descriptors for the baselines (without --map)")
      ->capture_default_str();
  cmd->add_option("--ransac-iterations", args->ransac_iterations, "RANSAC iterations")->capture_default_str();
  cmd->add_option("--inverted-file-words", args->inverted_file_words,
                  "The inverted-file rows: the candidates of a keypoint's N nearest words (1 = its own word)")
      ->capture_default_str();
  cmd->add_flag("!--no-popcount", args->popcount, "Skip the popcount baseline");
  cmd->add_option("--json", args->json, "Also write the figures as JSON");
  cmd->callback([args] { run_bench_infer(*args); });
}

}  // namespace lmb::bench
