// `lboost bench infer`: single-thread inference timings on a map's query frames, against OpenCV's
// BFMatcher (Hamming, 1-NN over every training observation's descriptor) measured in the same run.
#include <algorithm>
#include <chrono>
#include <cstdio>
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
#include "infer/localizer.h"
#include "infer/model.h"
#include "train/cli/commands.h"

namespace lmb::cli {

namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

struct BenchInferArgs {
  std::string model;
  std::string map;
  int keypoints = 1000;  // per frame: the first N of each query frame (all when fewer)
  int repeats = 3;
  int max_frames = 0;    // 0 = every query frame
  std::string json;
};

struct Sums {
  double embedding = 0, classification = 0, pose = 0, total = 0;
};

void run_bench_infer(const BenchInferArgs& a) {
  LMB_CHECK(a.keypoints >= 1 && a.repeats >= 1, "bench infer: --keypoints and --repeats must be >= 1");
  const auto model = Model::load(a.model);
  const LandmarkMap map = read_map_h5(a.map);
  LMB_CHECK(map.descriptor_bytes == model->descriptor_bytes(),
            a.map << ": descriptor length differs from the model's");
  const int bytes = map.descriptor_bytes;
  // Training descriptors for the baseline: every map-frame observation of a landmark.
  std::vector<uint8_t> train;
  for (const MapFrame& f : map.frames) {
    if (f.is_query) continue;
    for (int64_t k = f.first_keypoint; k < f.first_keypoint + f.num_keypoints; ++k) {
      if (map.keypoint_landmark[k] >= 0) train.insert(train.end(), map.descriptor(k), map.descriptor(k) + bytes);
    }
  }
  const int num_train = static_cast<int>(train.size() / bytes);
  LMB_CHECK(num_train > 0, a.map << ": no training observations");
  const cv::Mat train_mat(num_train, bytes, CV_8U, train.data());
  cv::BFMatcher bf(cv::NORM_HAMMING, false);

  std::vector<frame_t> frames;
  for (frame_t f = 0; f < map.num_frames(); ++f) {
    if (map.frames[f].is_query) frames.push_back(f);
  }
  if (a.max_frames > 0 && static_cast<int>(frames.size()) > a.max_frames) frames.resize(a.max_frames);
  LMB_CHECK(!frames.empty(), a.map << ": no query frames");

  LocalizerOptions dense_options, inverted_options;
  inverted_options.classifier.use_inverted_file = true;
  const Localizer dense(model, dense_options), inverted(model, inverted_options);
  Sums sd, si;
  double bf_ms = 0, popcount_ms = 0;
  int64_t keypoints_total = 0, checksum = 0;
  int runs = 0;
  for (int rep = 0; rep < a.repeats; ++rep) {
    for (frame_t f : frames) {
      const MapFrame& mf = map.frames[f];
      const int n = std::min(a.keypoints, mf.num_keypoints);
      const std::vector<Keypoint> kps(map.keypoints.begin() + mf.first_keypoint,
                                      map.keypoints.begin() + mf.first_keypoint + n);
      const uint8_t* desc = map.descriptor(mf.first_keypoint);
      const Camera& camera = map.cameras[mf.camera];
      for (int mode = 0; mode < 2; ++mode) {
        const LocalizeResult r = (mode ? inverted : dense).localize(camera, kps, desc, mf.gravity_in_cam);
        Sums& s = mode ? si : sd;
        s.embedding += r.timings.embedding_ms + r.timings.words_ms;
        s.classification += r.timings.classification_ms;
        s.pose += r.timings.pose_ms;
        s.total += r.timings.total_ms;
        checksum += r.pose.num_inliers;
      }
      const cv::Mat query(n, bytes, CV_8U, const_cast<uint8_t*>(desc));
      std::vector<cv::DMatch> matches;
      Clock::time_point t = Clock::now();
      bf.match(query, train_mat, matches);
      bf_ms += ms_since(t);
      t = Clock::now();
      for (int q = 0; q < n; ++q) {
        int best = 1 << 30;
        for (int j = 0; j < num_train; ++j) {
          best = std::min(best, hamming_distance(desc + static_cast<int64_t>(q) * bytes, train.data() + static_cast<int64_t>(j) * bytes, bytes));
        }
        checksum += best;
      }
      popcount_ms += ms_since(t);
      keypoints_total += n;
      ++runs;
    }
  }
  const double nr = runs;
  const double kp_per_frame = static_cast<double>(keypoints_total) / nr;
  const double match_dense = (sd.embedding + sd.classification) / nr;
  const double match_inverted = (si.embedding + si.classification) / nr;
  std::printf(
      "bench infer: model %d classes, %zu stumps, %zu used dims; %zu query frames x %d repeats, %.0f keypoints "
      "a frame; %d training descriptors (1 thread)\n",
      model->num_classes(), model->data().stumps.size(), model->used_dims().size(), frames.size(), a.repeats,
      kp_per_frame, num_train);
  std::printf("  dense:         embedding %.2f ms, classification %.2f ms, pose %.2f ms, total %.2f ms a frame\n",
              sd.embedding / nr, sd.classification / nr, sd.pose / nr, sd.total / nr);
  std::printf("  inverted file: embedding %.2f ms, classification %.2f ms, pose %.2f ms, total %.2f ms a frame\n",
              si.embedding / nr, si.classification / nr, si.pose / nr, si.total / nr);
  std::printf("  OpenCV BFMatcher (Hamming, 1-NN): %.2f ms a frame; popcount loop: %.2f ms a frame\n", bf_ms / nr,
              popcount_ms / nr);
  std::printf("  matching (embedding + classification) / BFMatcher: dense %.3f, inverted file %.3f (checksum %lld)\n",
              match_dense / (bf_ms / nr), match_inverted / (bf_ms / nr), static_cast<long long>(checksum));
  if (!a.json.empty()) {
    nlohmann::json j = {{"classes", model->num_classes()},
                        {"stumps", model->data().stumps.size()},
                        {"used_dims", model->used_dims().size()},
                        {"frames", frames.size()},
                        {"repeats", a.repeats},
                        {"keypoints_per_frame", kp_per_frame},
                        {"training_descriptors", num_train},
                        {"dense_ms", {{"embedding", sd.embedding / nr}, {"classification", sd.classification / nr},
                                      {"pose", sd.pose / nr}, {"total", sd.total / nr}}},
                        {"inverted_file_ms", {{"embedding", si.embedding / nr}, {"classification", si.classification / nr},
                                              {"pose", si.pose / nr}, {"total", si.total / nr}}},
                        {"bfmatcher_ms", bf_ms / nr},
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
  cmd->add_option("--model", args->model, "Inference model (model.lbm)")->required();
  cmd->add_option("--map", args->map, "Map whose query frames are used (map.h5)")->required();
  cmd->add_option("--keypoints", args->keypoints, "Keypoints a frame (the first N)")->capture_default_str();
  cmd->add_option("--repeats", args->repeats, "Passes over the frames")->capture_default_str();
  cmd->add_option("--max-frames", args->max_frames, "At most this many query frames (0 = all)")->capture_default_str();
  cmd->add_option("--json", args->json, "Also write the figures as JSON");
  cmd->callback([args] { run_bench_infer(*args); });
}

}  // namespace lmb::cli
