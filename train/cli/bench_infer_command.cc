// `lboost bench infer`: single-thread inference timings (context embedding, classification dense
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

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <spdlog/spdlog.h>

#include "common/error.h"
#include "common/hamming.h"
#include "common/io/map_h5.h"
#include "common/machine_info.h"
#include "common/random.h"
#include "common/context_embedding.h"
#include "infer/classifier.h"
#include "infer/localizer.h"
#include "infer/model.h"
#include "infer/pose_estimator.h"
#include "train/cli/commands.h"
#include "train/cli/timing.h"
#include "train/export/synthetic_model.h"

namespace lmb::cli {

namespace {

struct BenchInferArgs {
  std::string model;
  bool synthetic_paper = false;
  SyntheticModelOptions synthetic;
  std::string map;
  int keypoints = 1000;  // per frame: the first N of each query frame (all when fewer)
  int repeats = 3;
  int max_frames = 0;    // 0 = every query frame (map) / number of synthetic frames
  int frames = 5;        // synthetic frames (without --map)
  int train_descriptors = 400000;  // synthetic training descriptors (without --map)
  int ransac_iterations = 500;
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

void run_bench_infer(const BenchInferArgs& a) {
  LMB_CHECK(a.keypoints >= 1 && a.repeats >= 1, "bench infer: --keypoints and --repeats must be >= 1");
  LMB_CHECK(a.synthetic_paper != !a.model.empty(),
            "bench infer: give exactly one of --model and --synthetic-paper");
  std::shared_ptr<const Model> model;
  SyntheticModelStats synthetic_stats;
  Clock::time_point t_load = Clock::now();
  if (a.synthetic_paper) {
    model = std::make_shared<const Model>(make_synthetic_model(a.synthetic, &synthetic_stats));
  } else {
    model = Model::load(a.model);
  }
  const double load_ms = ms_since(t_load);
  const int bytes = model->descriptor_bytes();

  std::vector<BenchFrame> frames;
  std::vector<uint8_t> train;  // training descriptors for the baselines
  if (!a.map.empty()) {
    const LandmarkMap map = read_map_h5(a.map);
    LMB_CHECK(map.descriptor_bytes == bytes, a.map << ": descriptor length differs from the model's");
    // Every map-frame observation of a landmark.
    for (const MapFrame& f : map.frames) {
      if (f.is_query) continue;
      for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
        if (map.keypoint_landmark[k] >= 0) train.insert(train.end(), map.descriptor(k), map.descriptor(k) + bytes);
      }
    }
    for (const MapFrame& mf : map.frames) {
      if (!mf.is_query) continue;
      if (a.max_frames > 0 && static_cast<int>(frames.size()) >= a.max_frames) break;
      const int n = std::min(a.keypoints, mf.num_keypoints);
      BenchFrame f;
      f.camera = map.cameras[mf.camera];
      f.gravity_in_cam = mf.gravity_in_cam;
      f.keypoints.assign(map.keypoints.begin() + mf.first_keypoint, map.keypoints.begin() + mf.first_keypoint + n);
      f.descriptors.assign(map.descriptor(mf.first_keypoint), map.descriptor(mf.first_keypoint) + static_cast<int64_t>(n) * bytes);
      frames.push_back(std::move(f));
    }
    LMB_CHECK(!frames.empty(), a.map << ": no query frames");
  } else {
    LMB_CHECK(a.frames >= 1 && a.train_descriptors >= 1,
              "bench infer: --frames and --train-descriptors must be >= 1");
    frames = synthetic_frames(a.max_frames > 0 ? std::min(a.frames, a.max_frames) : a.frames, a.keypoints, bytes,
                              a.synthetic.seed + 1);
    Rng rng(a.synthetic.seed + 2);
    train.resize(static_cast<size_t>(a.train_descriptors) * bytes);
    for (uint8_t& b : train) b = static_cast<uint8_t>(rng.below(256));
  }
  const int num_train = static_cast<int>(train.size() / bytes);
  LMB_CHECK(num_train > 0, "bench infer: no training descriptors");
  // OpenCV's BFMatcher takes at most 2^18 rows per training image: the descriptors go in as a
  // collection of chunks (matched all at once by match / knnMatch).
  cv::BFMatcher bf(cv::NORM_HAMMING, false);
  {
    constexpr int kChunk = 1 << 17;
    std::vector<cv::Mat> chunks;
    for (int first = 0; first < num_train; first += kChunk) {
      chunks.emplace_back(std::min(kChunk, num_train - first), bytes, CV_8U,
                          train.data() + static_cast<int64_t>(first) * bytes);
    }
    bf.add(chunks);
    bf.train();
  }

  LocalizerOptions dense_options;
  dense_options.pose.max_iterations = a.ransac_iterations;
  LocalizerOptions inverted_options = dense_options;
  inverted_options.classifier.use_inverted_file = true;
  const Localizer dense(model, dense_options), inverted(model, inverted_options);
  Sums sd, si;
  double bf_ms = 0, bf_knn_ms = 0, popcount_ms = 0, bf_cpu_ms = 0;
  int64_t keypoints_total = 0, checksum = 0, correspondences = 0, inliers = 0;
  int runs = 0;
  for (int rep = 0; rep < a.repeats; ++rep) {
    for (const BenchFrame& f : frames) {
      const int n = static_cast<int>(f.keypoints.size());
      const uint8_t* desc = f.descriptors.data();
      for (int mode = 0; mode < 2; ++mode) {
        const double cpu0 = thread_cpu_ms();
        const LocalizeResult r = (mode ? inverted : dense).localize(f.camera, f.keypoints, desc, f.gravity_in_cam);
        Sums& s = mode ? si : sd;
        s.cpu += thread_cpu_ms() - cpu0;
        s.embedding += r.timings.embedding_ms + r.timings.words_ms;
        s.classification += r.timings.classification_ms;
        s.pose += r.timings.pose_ms;
        s.total += r.timings.total_ms;
        if (mode) {
          correspondences += static_cast<int64_t>(r.correspondence_keypoint.size());
          inliers += r.pose.num_inliers;
        }
      }
      const cv::Mat query(n, bytes, CV_8U, const_cast<uint8_t*>(desc));
      std::vector<cv::DMatch> matches;
      Clock::time_point t = Clock::now();
      const double cpu0 = thread_cpu_ms();
      bf.match(query, matches);
      bf_cpu_ms += thread_cpu_ms() - cpu0;
      bf_ms += ms_since(t);
      std::vector<std::vector<cv::DMatch>> knn;
      t = Clock::now();
      bf.knnMatch(query, knn, 2);
      bf_knn_ms += ms_since(t);
      checksum += static_cast<int64_t>(matches.size() + knn.size());
      if (a.popcount) {
        t = Clock::now();
        for (int q = 0; q < n; ++q) {
          int best = 1 << 30;
          for (int j = 0; j < num_train; ++j) {
            best = std::min(best, hamming_distance(desc + static_cast<int64_t>(q) * bytes,
                                                   train.data() + static_cast<int64_t>(j) * bytes, bytes));
          }
          checksum += best;
        }
        popcount_ms += ms_since(t);
      }
      keypoints_total += n;
      ++runs;
    }
  }
  // Thread CPU of each stage with the inverted file (the localizer's timings are wall clock, which
  // a busy machine inflates): each stage run on its own, frame by frame. Embedding = descriptor
  // quantization, keypoint normalization, and classify()'s own frame index and dims (its
  // embedding_ms: one thread, so wall = CPU but for preemption); scoring = the rest of classify();
  // pose = estimate_absolute_pose on the localizer's correspondences.
  // Also the scoring without screening (ClassifierOptions::screening = false), for the ratio.
  double stage_embedding = 0, stage_scoring = 0, stage_pose = 0, stage_unscreened = 0;
  double scored_share = 0;
  {
    Classifier classifier(model, inverted_options.classifier);
    ClassifierOptions unscreened_options = inverted_options.classifier;
    unscreened_options.screening = false;
    Classifier unscreened(model, unscreened_options);
    for (int rep = 0; rep < a.repeats; ++rep) {
      for (const BenchFrame& f : frames) {
        const int n = static_cast<int>(f.keypoints.size());
        const uint8_t* desc = f.descriptors.data();
        const LocalizeResult r = inverted.localize(f.camera, f.keypoints, desc, f.gravity_in_cam);
        const double t0 = thread_cpu_ms();
        std::vector<uint8_t> words(static_cast<size_t>(n));
        model->vocabulary().quantize(desc, n, words.data());
        const FrameKeypoints fk = frame_keypoints_from_detections(f.camera, f.keypoints.data(), words.data(), n,
                                                                  f.gravity_in_cam, "bench");
        const double t1 = thread_cpu_ms();
        double embedding_ms = 0, unscreened_embedding_ms = 0;
        checksum += static_cast<int64_t>(classifier.classify(fk, desc, "bench", &embedding_ms).matches.size());
        const double t3 = thread_cpu_ms();
        checksum += static_cast<int64_t>(unscreened.classify(fk, desc, "bench", &unscreened_embedding_ms).matches.size());
        stage_unscreened += thread_cpu_ms() - t3 - unscreened_embedding_ms;
        std::vector<Eigen::Vector2d> pixels;
        std::vector<Eigen::Vector3d> points;
        for (size_t i = 0; i < r.correspondence_keypoint.size(); ++i) {
          const Keypoint& kp = f.keypoints[r.correspondence_keypoint[i]];
          pixels.emplace_back(kp.x, kp.y);
          points.push_back(model->class_position(r.matches.matches[r.correspondence_match[i]].cls));
        }
        const double t4 = thread_cpu_ms();
        checksum += estimate_absolute_pose(f.camera, pixels, points, inverted_options.pose).num_inliers;
        const double t5 = thread_cpu_ms();
        stage_embedding += (t1 - t0) + embedding_ms;
        stage_scoring += (t3 - t1) - embedding_ms;
        stage_pose += t5 - t4;
      }
    }
    scored_share = static_cast<double>(classifier.classes_scored()) /
                   static_cast<double>(std::max<int64_t>(1, classifier.classes_screened()));
  }
  // The unbatched path (one keypoint at a time: Classifier::dense_scores, and class_score over the
  // word's candidates), on the first frame, for the speed-up of the batched classify().
  double unbatched_dense_ms = 0, unbatched_inverted_ms = 0;
  {
    const BenchFrame& f = frames.front();
    const int n = static_cast<int>(f.keypoints.size());
    std::vector<uint8_t> words(static_cast<size_t>(n));
    model->vocabulary().quantize(f.descriptors.data(), n, words.data());
    const FrameKeypoints fk = frame_keypoints_from_detections(f.camera, f.keypoints.data(), words.data(), n,
                                                              f.gravity_in_cam, "bench");
    Classifier c(model);
    c.index_frame(fk);
    std::vector<uint8_t> values(model->used_dims().size());
    std::vector<double> scores(static_cast<size_t>(model->num_classes()) + 1);
    double sink = 0;
    for (int k = 0; k < n; ++k) {
      c.compute_used_values(k, f.descriptors.data() + static_cast<int64_t>(k) * bytes, values.data());
      Clock::time_point t = Clock::now();
      c.dense_scores(values.data(), scores.data());
      sink += scores[0];
      unbatched_dense_ms += ms_since(t);
      t = Clock::now();
      const int32_t w = fk.word[k];
      for (int32_t i = model->word_class_begin()[w]; i < model->word_class_begin()[w + 1]; ++i) {
        sink += c.class_score(values.data(), model->word_classes()[i]);
      }
      sink += c.class_score(values.data(), model->background_class());
      unbatched_inverted_ms += ms_since(t);
    }
    checksum += static_cast<int64_t>(sink) & 1;
  }
  const double nr = runs;
  const double kp_per_frame = static_cast<double>(keypoints_total) / nr;
  const double match_dense = (sd.embedding + sd.classification) / nr;
  const double match_inverted = (si.embedding + si.classification) / nr;
  const Model& m = *model;
  std::printf(
      "bench infer: %s model: %d classes, %zu stumps, %lld sharing entries, %zu used dims, %lld inverted-file "
      "entries (built/loaded in %.0f ms)\n",
      a.synthetic_paper ? "synthetic" : "trained", m.num_classes(), m.data().stumps.size(),
      static_cast<long long>(m.stump_classes().size()), m.used_dims().size(),
      static_cast<long long>(m.word_classes().size()), load_ms);
  const std::string machine = machine_info().summary();
  std::printf("  machine: %s\n", machine.c_str());
  std::printf("  %zu %s frames x %d repeats, %.0f keypoints a frame; %d training descriptors; 1 thread; %d RANSAC iterations\n",
              frames.size(), a.map.empty() ? "synthetic" : "query", a.repeats, kp_per_frame, num_train,
              a.ransac_iterations);
  std::printf("  dense:         embedding %.2f ms, classification %.2f ms, pose %.2f ms, total %.2f ms a frame\n",
              sd.embedding / nr, sd.classification / nr, sd.pose / nr, sd.total / nr);
  std::printf("  inverted file: embedding %.2f ms, classification %.2f ms, pose %.2f ms, total %.2f ms a frame "
              "(%.0f correspondences, %.1f inliers)\n",
              si.embedding / nr, si.classification / nr, si.pose / nr, si.total / nr, correspondences / nr,
              inliers / nr);
  std::printf("  unbatched scoring (one keypoint at a time, first frame): dense %.2f ms, inverted file %.2f ms a frame\n",
              unbatched_dense_ms, unbatched_inverted_ms);
  std::printf("  OpenCV BFMatcher (Hamming): 1-NN %.2f ms, 2-NN %.2f ms a frame; popcount 1-NN loop: %.2f ms a frame\n",
              bf_ms / nr, bf_knn_ms / nr, popcount_ms / nr);
  std::printf("  thread CPU time a frame: localization dense %.2f ms, inverted file %.2f ms; BFMatcher 1-NN %.2f ms "
              "(inverted-file localization / BFMatcher 1-NN: 1/%.1f)\n",
              sd.cpu / nr, si.cpu / nr, bf_cpu_ms / nr, bf_cpu_ms / si.cpu);
  std::printf("  thread CPU time a frame by stage, inverted file (each stage run on its own): embedding %.2f ms, "
              "scoring %.2f ms, pose %.2f ms\n",
              stage_embedding / nr, stage_scoring / nr, stage_pose / nr);
  std::printf("  screening: %.2f%% of the candidate classes scored exactly; scoring without screening %.2f ms "
              "(%.1fx)\n",
              100.0 * scored_share, stage_unscreened / nr, stage_unscreened / stage_scoring);
  std::printf("  matching (embedding + classification) / BFMatcher 1-NN: dense %.4f (1/%.1f), inverted file %.4f "
              "(1/%.1f) (checksum %lld)\n",
              match_dense / (bf_ms / nr), bf_ms / nr / match_dense, match_inverted / (bf_ms / nr),
              bf_ms / nr / match_inverted, static_cast<long long>(checksum));
  if (!a.json.empty()) {
    nlohmann::json j = {{"model", a.synthetic_paper ? "synthetic" : a.model},
                        {"machine", machine},
                        {"classes", m.num_classes()},
                        {"stumps", m.data().stumps.size()},
                        {"sharing_entries", m.stump_classes().size()},
                        {"used_dims", m.used_dims().size()},
                        {"inverted_file_entries", m.word_classes().size()},
                        {"frames", frames.size()},
                        {"repeats", a.repeats},
                        {"keypoints_per_frame", kp_per_frame},
                        {"training_descriptors", num_train},
                        {"ransac_iterations", a.ransac_iterations},
                        {"dense_ms", {{"embedding", sd.embedding / nr}, {"classification", sd.classification / nr},
                                      {"pose", sd.pose / nr}, {"total", sd.total / nr}}},
                        {"inverted_file_ms", {{"embedding", si.embedding / nr}, {"classification", si.classification / nr},
                                              {"pose", si.pose / nr}, {"total", si.total / nr}}},
                        {"cpu_ms", {{"dense_localization", sd.cpu / nr}, {"inverted_file_localization", si.cpu / nr},
                                    {"bfmatcher", bf_cpu_ms / nr},
                                    {"inverted_file_stages", {{"embedding", stage_embedding / nr},
                                                              {"scoring", stage_scoring / nr},
                                                              {"pose", stage_pose / nr},
                                                              {"scoring_unscreened", stage_unscreened / nr}}}}},
                        {"screening_scored_share", scored_share},
                        {"unbatched_scoring_ms", {{"dense", unbatched_dense_ms}, {"inverted_file", unbatched_inverted_ms}}},
                        {"bfmatcher_ms", bf_ms / nr},
                        {"bfmatcher_knn2_ms", bf_knn_ms / nr},
                        {"popcount_ms", popcount_ms / nr},
                        {"match_ratio_dense", match_dense / (bf_ms / nr)},
                        {"match_ratio_inverted_file", match_inverted / (bf_ms / nr)}};
    std::ofstream(a.json) << j.dump(1) << "\n";
  }
}

}  // namespace

void add_bench_infer_command(CLI::App& app) {
  CLI::App* bench = app.get_subcommand("bench");
  auto args = std::make_shared<BenchInferArgs>();
  auto* cmd = bench->add_subcommand(
      "infer", "Inference timings (embedding, classification dense / inverted file, pose) vs OpenCV BFMatcher");
  cmd->add_option("--model", args->model, "Inference model (model.lbm)");
  cmd->add_flag("--synthetic-paper", args->synthetic_paper,
                "Instead of --model: a random model of the paper's shape (7,500 classes, 2,000 stumps)");
  cmd->add_option("--classes", args->synthetic.num_classes, "Synthetic model: classes")->capture_default_str();
  cmd->add_option("--stumps", args->synthetic.num_stumps, "Synthetic model: stumps")->capture_default_str();
  cmd->add_option("--seed", args->synthetic.seed, "Synthetic model and frames: seed")->capture_default_str();
  cmd->add_option("--map", args->map, "Map whose query frames and training observations are used (map.h5); "
                                      "default: synthetic frames and descriptors");
  cmd->add_option("--keypoints", args->keypoints, "Keypoints a frame (the first N)")->capture_default_str();
  cmd->add_option("--repeats", args->repeats, "Passes over the frames")->capture_default_str();
  cmd->add_option("--max-frames", args->max_frames, "At most this many query frames (0 = all)")->capture_default_str();
  cmd->add_option("--frames", args->frames, "Synthetic frames (without --map)")->capture_default_str();
  cmd->add_option("--train-descriptors", args->train_descriptors,
                  "Synthetic training descriptors for the baselines (without --map)")->capture_default_str();
  cmd->add_option("--ransac-iterations", args->ransac_iterations, "RANSAC iterations")->capture_default_str();
  cmd->add_flag("!--no-popcount", args->popcount, "Skip the popcount baseline");
  cmd->add_option("--json", args->json, "Also write the figures as JSON");
  cmd->callback([args] { run_bench_infer(*args); });
}

}  // namespace lmb::cli
