#include "train/world/texture.h"

#include <gtest/gtest.h>

#include "common/error.h"

namespace lmb {
namespace {

TEST(TextureTest, MipPyramidAveragesAndSamplesTexelCentres) {
  // A 4x2 checker of 0 and 255 over 2 m x 1 m.
  cv::Mat m(2, 4, CV_8UC1);
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 4; ++c) m.at<uint8_t>(r, c) = ((r + c) % 2) ? 255 : 0;
  const Texture t(m, 2.0, 1.0);
  EXPECT_EQ(t.num_levels(), 3);  // 4x2, 2x1, 1x1
  EXPECT_DOUBLE_EQ(t.texels_per_metre(), 2.0);
  // Texel centres of level 0 return the texel exactly.
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < 4; ++c) {
      EXPECT_FLOAT_EQ(t.sample((c + 0.5) / 4, (r + 0.5) / 2, 0.0), m.at<uint8_t>(r, c) / 255.0f);
    }
  }
  // Coarser levels average the checker to mid-grey.
  EXPECT_NEAR(t.sample(0.3, 0.6, 2.0), 127.5f / 255.0f, 1.0f / 255.0f);
  EXPECT_NEAR(t.sample(0.3, 0.6, 1.0), 127.5f / 255.0f, 1.0f / 255.0f);
  // Halfway between level 0 and level 2 at a black texel: halfway between 0 and grey.
  EXPECT_NEAR(t.sample(0.125, 0.25, 0.5), 0.5f * 127.5f / 255.0f, 1.0f / 255.0f);
  // Clamped outside [0, 1].
  EXPECT_FLOAT_EQ(t.sample(-3.0, -3.0, 0.0), t.sample(0.0, 0.0, 0.0));
}

TEST(TextureTest, RejectsBadInput) {
  EXPECT_THROW(Texture(cv::Mat(), 1.0, 1.0), Error);
  EXPECT_THROW(Texture(cv::Mat(2, 2, CV_8UC1, cv::Scalar(1)), 0.0, 1.0), Error);
}

bool same_pixels(const Texture& a, const Texture& b) {
  const cv::Mat& x = a.level(0);
  const cv::Mat& y = b.level(0);
  return x.size() == y.size() && cv::countNonZero(x != y) == 0;
}

TEST(TextureTest, GeneratorsArePureFunctionsOfTheSeed) {
  EXPECT_TRUE(same_pixels(make_door_texture(5, 0.95, 2.1), make_door_texture(5, 0.95, 2.1)));
  EXPECT_FALSE(same_pixels(make_door_texture(5, 0.95, 2.1), make_door_texture(6, 0.95, 2.1)));
  EXPECT_TRUE(same_pixels(make_poster_texture(9, 0.6, 0.85), make_poster_texture(9, 0.6, 0.85)));
  EXPECT_FALSE(same_pixels(make_poster_texture(9, 0.6, 0.85), make_poster_texture(10, 0.6, 0.85)));
  EXPECT_FALSE(same_pixels(make_floor_tile_texture(1, 0.5), make_floor_tile_texture(2, 0.5)));
  EXPECT_FALSE(same_pixels(make_plate_texture(1, "F1.01", 0.22, 0.12, false),
                           make_plate_texture(1, "F1.03", 0.22, 0.12, false)));
  const Texture door = make_door_texture(1, 0.95, 2.1);
  EXPECT_EQ(door.level(0).cols, 380);
  EXPECT_EQ(door.level(0).rows, 840);
}

TEST(TextureTest, StainsOnlyDarken) {
  const Texture s = make_stain_texture(3, 0.3, 0.2);
  double min_value = 0, max_value = 0;
  cv::minMaxLoc(s.level(0), &min_value, &max_value);
  EXPECT_EQ(max_value, 255.0);  // untouched texels leave the surface unchanged
  EXPECT_LT(min_value, 200.0);  // and the stain is visible
}

}  // namespace
}  // namespace lmb
