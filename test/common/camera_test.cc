#include "common/camera.h"

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/random.h"

namespace lmb {
namespace {

Camera make(CameraModel model, std::vector<double> params) {
  Camera c;
  c.model = model;
  c.width = 640;
  c.height = 480;
  c.params = std::move(params);
  c.check();
  return c;
}

std::vector<Camera> all_models() {
  return {
      make(CameraModel::kSimplePinhole, {500, 320, 240}),
      make(CameraModel::kPinhole, {510, 490, 318, 241}),
      make(CameraModel::kSimpleRadial, {500, 320, 240, -0.08}),
      make(CameraModel::kRadial, {500, 320, 240, -0.1, 0.02}),
      make(CameraModel::kOpenCV, {510, 490, 318, 241, -0.2, 0.05, 0.001, -0.002}),
      // The TUM freiburg1 calibration: strong distortion with k3 > 1.
      make(CameraModel::kFullOpenCV,
           {517.3, 516.5, 318.6, 255.3, 0.2624, -0.9531, -0.0054, 0.0026, 1.1633, 0, 0, 0}),
  };
}

TEST(Camera, KnownProjectionValues) {
  // Hand-computed from COLMAP's definitions.
  const Camera pinhole = make(CameraModel::kPinhole, {500, 400, 320, 240});
  EXPECT_TRUE(pinhole.img_from_cam({0.1, -0.2}).isApprox(Eigen::Vector2d(370, 160)));

  // SIMPLE_RADIAL: u=(0.2, 0.1), r2=0.05, k=-0.1: factor 1 - 0.005 = 0.995.
  const Camera sr = make(CameraModel::kSimpleRadial, {500, 320, 240, -0.1});
  EXPECT_TRUE(sr.img_from_cam({0.2, 0.1}).isApprox(Eigen::Vector2d(320 + 500 * 0.2 * 0.995,
                                                                   240 + 500 * 0.1 * 0.995)));

  // OPENCV tangential terms only: p1=0.01, p2=0.02, u=(0.3, 0.4): uv=0.12, r2=0.25.
  const Camera cv = make(CameraModel::kOpenCV, {100, 100, 0, 0, 0, 0, 0.01, 0.02});
  const double du = 2 * 0.01 * 0.12 + 0.02 * (0.25 + 2 * 0.09);
  const double dv = 2 * 0.02 * 0.12 + 0.01 * (0.25 + 2 * 0.16);
  EXPECT_TRUE(cv.img_from_cam({0.3, 0.4}).isApprox(Eigen::Vector2d(100 * (0.3 + du), 100 * (0.4 + dv))));

  // FULL_OPENCV rational radial term: k1=0.1, k4=0.2, r2=0.25 -> (1.025)/(1.05).
  const Camera full = make(CameraModel::kFullOpenCV, {100, 100, 0, 0, 0.1, 0, 0, 0, 0, 0.2, 0, 0});
  const double factor = 1.025 / 1.05;
  EXPECT_TRUE(full.img_from_cam({0.3, 0.4}).isApprox(Eigen::Vector2d(30 * factor, 40 * factor)));
}

TEST(Camera, UndistortionInvertsDistortionOverTheImage) {
  for (const Camera& camera : all_models()) {
    for (int y = 0; y <= camera.height; y += 40) {
      for (int x = 0; x <= camera.width; x += 40) {
        const Eigen::Vector2d pixel(x, y);
        const Eigen::Vector2d n = camera.cam_from_img(pixel);
        const Eigen::Vector2d back = camera.img_from_cam(n);
        EXPECT_LT((back - pixel).norm(), 1e-6)
            << camera_model_name(camera.model) << " at " << x << "," << y;
      }
    }
  }
}

TEST(Camera, ProjectRejectsPointsBehind) {
  const Camera c = all_models()[1];
  Eigen::Vector2d px;
  EXPECT_FALSE(c.project({0, 0, -1}, &px));
  EXPECT_FALSE(c.project({0, 0, 0}, &px));
  ASSERT_TRUE(c.project({0, 0, 2}, &px));
  EXPECT_TRUE(px.isApprox(c.principal_point()));
}

TEST(Camera, RejectsBadModelsAndParameters) {
  EXPECT_THROW(camera_model_from_name("OPENCV_FISHEYE"), Error);
  EXPECT_THROW(camera_model_from_id(5), Error);
  EXPECT_THROW(camera_model_from_id(42), Error);
  Camera c = make(CameraModel::kPinhole, {500, 500, 320, 240});
  c.params.pop_back();
  EXPECT_THROW(c.check(), Error);
  c.params = {500, std::nan(""), 320, 240};
  EXPECT_THROW(c.check(), Error);
  c.params = {-1, 500, 320, 240};
  EXPECT_THROW(c.check(), Error);
  c.params = {500, 500, 320, 240};
  c.width = 0;
  EXPECT_THROW(c.check(), Error);
  for (int id : {0, 1, 2, 3, 4, 6}) {
    EXPECT_EQ(static_cast<int>(camera_model_from_id(id)), id);
    EXPECT_EQ(camera_model_from_name(camera_model_name(camera_model_from_id(id))), camera_model_from_id(id));
  }
}

}  // namespace
}  // namespace lmb
