#include "train/boost/round_log.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace lmb {
namespace {

TEST(RoundLogger, WritesOneJsonLinePerRound) {
  const auto path = std::filesystem::temp_directory_path() / "lmb_round_log_test_metrics.jsonl";
  std::filesystem::remove(path);
  {
    RoundLogger log(path, 3);
    RoundStats s;
    s.round = 0;
    s.cost = 10.0;
    s.validation_p1 = 0.25;
    s.sharing_size = 7;
    s.seconds = 2.0;
    log.log(s);
    s.round = 1;
    s.validation_p1 = -1.0;  // not evaluated
    log.log(s);
  }
  std::ifstream in(path);
  std::string line;
  std::vector<nlohmann::json> rows;
  while (std::getline(in, line)) rows.push_back(nlohmann::json::parse(line));
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0]["round"], 0);
  EXPECT_DOUBLE_EQ(rows[0]["validation_p1"].get<double>(), 0.25);
  EXPECT_EQ(rows[0]["sharing_size"], 7);
  EXPECT_DOUBLE_EQ(rows[0]["eta_seconds"].get<double>(), 4.0);  // 2 s x 2 rounds left
  EXPECT_TRUE(rows[1]["validation_p1"].is_null());
  EXPECT_DOUBLE_EQ(rows[1]["eta_seconds"].get<double>(), 2.0);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace lmb
