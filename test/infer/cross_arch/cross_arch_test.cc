// The same model and frames localized on another build (another architecture, or this one) give
// the same result: replays a case written by lmb_cross_case (localize_case.h) and compares this
// build's transcript with the writer's. Matches (classes, ranks, scores and background scores,
// every bit) and the poses' success, inlier counts and inlier masks must be identical; the poses'
// rotation and translation must agree to 1e-9 (OpenGV and libm are prebuilt per architecture:
// Debian's arm64 OpenGV is compiled with fused multiply-adds, so its last bits may differ), and
// the test prints how many are bit-identical.
//   LMB_CROSS_CASE=DIR: the case (model.lbm, frames.bin, expected.txt); skipped when unset, and a
//   failure when LMB_CROSS_CASE_REQUIRED=1 (scripts/cross_test.sh).
// The transcript of this build goes to DIR/actual-<architecture>-<SIMD level>.txt.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/simd/simd_level.h"
#include "infer/localizer.h"
#include "infer/model.h"
#include "test/infer/cross_arch/localize_case.h"

namespace lmb {
namespace {

#if defined(__x86_64__)
constexpr const char* kArchitecture = "x86_64";
#elif defined(__aarch64__)
constexpr const char* kArchitecture = "aarch64";
#else
constexpr const char* kArchitecture = "other";
#endif

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) lines.push_back(line);
  return lines;
}

std::vector<double> pose_numbers(const std::string& line) {
  std::istringstream in(line.substr(std::string("cam_from_world ").size()));
  std::vector<double> v;
  std::string word;
  while (in >> word) v.push_back(std::strtod(word.c_str(), nullptr));
  return v;
}

TEST(CrossArch, LocalizationEqualsTheWritingBuildsTranscript) {
  const char* dir_env = std::getenv("LMB_CROSS_CASE");
  const bool required =
      std::getenv("LMB_CROSS_CASE_REQUIRED") != nullptr && std::string(std::getenv("LMB_CROSS_CASE_REQUIRED")) == "1";
  const std::filesystem::path dir = dir_env ? dir_env : "";
  if (dir_env == nullptr || !std::filesystem::exists(dir / "expected.txt")) {
    if (required) FAIL() << "LMB_CROSS_CASE=" << (dir_env ? dir_env : "") << " holds no case (expected.txt)";
    GTEST_SKIP() << "LMB_CROSS_CASE (a case written by lmb_cross_case) is not set or holds no case";
  }
  uint32_t bytes = 0;
  const std::vector<test::CaseFrame> frames = test::read_case_frames((dir / "frames.bin").string(), &bytes);
  const std::shared_ptr<const Model> model = Model::load(dir / "model.lbm");
  ASSERT_EQ(static_cast<int32_t>(bytes), model->descriptor_bytes());
  std::string actual;
  for (const auto& [setting, options] : test::case_settings()) {
    const Localizer localizer(model, options);
    for (const test::CaseFrame& f : frames) {
      actual += test::transcript(f.name, setting,
                                 localizer.localize(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam));
    }
  }
  const std::string out_name = std::string("actual-") + kArchitecture + "-" + simd_level_name(simd_level()) + ".txt";
  std::ofstream(dir / out_name) << actual;
  std::ifstream in(dir / "expected.txt");
  std::stringstream expected_text;
  expected_text << in.rdbuf();
  const std::vector<std::string> want = lines_of(expected_text.str()), got = lines_of(actual);
  ASSERT_EQ(got.size(), want.size()) << "transcripts of different lengths: " << (dir / out_name);
  int match_lines = 0, poses = 0, identical_poses = 0, successes = 0;
  double max_difference = 0.0;
  for (size_t i = 0; i < want.size(); ++i) {
    if (want[i].rfind("cam_from_world ", 0) == 0) {
      ASSERT_EQ(got[i].rfind("cam_from_world ", 0), 0u) << "line " << i + 1;
      const std::vector<double> a = pose_numbers(want[i]), b = pose_numbers(got[i]);
      ASSERT_EQ(a.size(), 7u);
      ASSERT_EQ(b.size(), 7u);
      for (int j = 0; j < 7; ++j) {
        max_difference = std::max(max_difference, std::fabs(a[j] - b[j]));
        EXPECT_NEAR(b[j], a[j], 1e-9) << "line " << i + 1 << ": " << want[i] << " vs " << got[i];
      }
      ++poses;
      identical_poses += got[i] == want[i];
      continue;
    }
    ASSERT_EQ(got[i], want[i]) << "line " << i + 1 << " of " << (dir / out_name);
    match_lines += want[i].rfind("match ", 0) == 0;
    successes += want[i].rfind("pose success 1", 0) == 0;
  }
  std::printf(
      "%s, SIMD level %s: %zu frames x %zu settings, %d matches identical; %d of %d poses found, %d of %d "
      "pose lines bit-identical, largest difference %.3g\n",
      kArchitecture, simd_level_name(simd_level()), frames.size(), test::case_settings().size(), match_lines, successes,
      poses, identical_poses, poses, max_difference);
  EXPECT_GT(match_lines, 100) << "the case should exercise the classifier";
  EXPECT_GT(successes, 0) << "the case should exercise the pose estimator";
}

}  // namespace
}  // namespace lmb
