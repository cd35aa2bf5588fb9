// The synthetic paper-shaped model of `lboost-bench infer --synthetic-paper`: the requested shape,
// valid, deterministic, sharing sets shrinking over the rounds, an inverted file covering every
// class; and a smoke run of the benchmark command at a small scale.
#include "train/export/synthetic_model.h"
#include "infer/detail/model_format.h"
#include "infer/detail/scoring_index.h"

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/error.h"

namespace lmb {
namespace {

TEST(SyntheticModelTest, HasThePaperShape) {
  SyntheticModelOptions o;
  o.num_classes = 1500;  // the paper's 7,500 classes take longer; the shape is the same
  SyntheticModelStats stats;
  const ModelData d = make_synthetic_model(o, &stats);
  d.check();
  EXPECT_EQ(d.num_classes, 1500);
  EXPECT_EQ(d.stumps.size(), 2000u);
  EXPECT_EQ(d.regions.size(), 1000);
  EXPECT_EQ(d.vocabulary.num_words(), 16);
  EXPECT_EQ(detail::layout_of(d).num_dims(), 1000 * 16 + 512);
  int context = 0;
  int64_t first = 0, last = 0;
  for (size_t m = 0; m < d.stumps.size(); ++m) {
    context += detail::layout_of(d).is_context(d.stumps[m].dim);
    if (m < 100) first += static_cast<int64_t>(d.stumps[m].classes.size());
    if (m >= d.stumps.size() - 100) last += static_cast<int64_t>(d.stumps[m].classes.size());
  }
  EXPECT_NEAR(context, 985, 80);  // the paper: 985 context and 1,015 descriptor stumps
  EXPECT_GT(first, 5 * last);     // large sharing sets first, small ones later
  EXPECT_GT(first / 100, 1500 / 8);
  std::vector<int> words_of_class(1500, 0);
  for (const auto& list : d.inverted_file) {
    for (int32_t c : list) ++words_of_class[c];
  }
  for (int c = 0; c < 1500; ++c) ASSERT_GE(words_of_class[c], 1) << "class " << c;
  int64_t entries = 0;
  for (const SharedStump& s : d.stumps) entries += static_cast<int64_t>(s.classes.size());
  EXPECT_EQ(stats.sharing_entries, entries);

  // Deterministic per seed; another seed gives another model.
  EXPECT_EQ(serialize_model_data(make_synthetic_model(o)), serialize_model_data(d));
  o.seed = 2;
  EXPECT_NE(serialize_model_data(make_synthetic_model(o)), serialize_model_data(d));
  o.num_words = 3;
  EXPECT_THROW(make_synthetic_model(o), Error);
}

TEST(SyntheticModelTest, BenchInferRunsOnIt) {
  const std::filesystem::path json =
      std::filesystem::temp_directory_path() / ("lmb_bench_infer_" + std::to_string(::getpid()) + ".json");
  const std::string command = std::string(LMB_LBOOST_BENCH) +
                              " infer --synthetic-paper --classes 200 --stumps 100 --frames 2 "
                              "--keypoints 150 --train-descriptors 2000 --repeats 1 --json " +
                              json.string();
  ASSERT_EQ(std::system(command.c_str()), 0) << command;
  std::ifstream in(json);
  const nlohmann::json j = nlohmann::json::parse(in);
  std::filesystem::remove(json);
  EXPECT_EQ(j["classes"], 200);
  EXPECT_EQ(j["stumps"], 100);
  EXPECT_EQ(j["training_descriptors"], 2000);
  EXPECT_GT(j["inverted_file_ms"]["total"].get<double>(), 0.0);
  EXPECT_GT(j["bfmatcher_ms"].get<double>(), 0.0);
}

}  // namespace
}  // namespace lmb
