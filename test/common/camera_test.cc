#include "common/camera.h"

#include <string>
#include <vector>

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
      make(CameraModel::kFullOpenCV, {517.3, 516.5, 318.6, 255.3, 0.2624, -0.9531, -0.0054, 0.0026, 1.1633, 0, 0, 0}),
  };
}

TEST(Camera, KnownProjectionValues) {
  // Hand-computed from COLMAP's definitions.
  const Camera pinhole = make(CameraModel::kPinhole, {500, 400, 320, 240});
  EXPECT_TRUE(pinhole.img_from_cam({0.1, -0.2}).isApprox(Eigen::Vector2d(370, 160)));

  // SIMPLE_RADIAL: u=(0.2, 0.1), r2=0.05, k=-0.1: factor 1 - 0.005 = 0.995.
  const Camera sr = make(CameraModel::kSimpleRadial, {500, 320, 240, -0.1});
  EXPECT_TRUE(sr.img_from_cam({0.2, 0.1}).isApprox(Eigen::Vector2d(320 + 500 * 0.2 * 0.995, 240 + 500 * 0.1 * 0.995)));

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
        EXPECT_LT((back - pixel).norm(), 1e-6) << camera_model_name(camera.model) << " at " << x << "," << y;
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
  EXPECT_THROW(camera_model_from_name("OPENCV_FISHEYE", "test"), Error);
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
    EXPECT_EQ(camera_model_from_name(camera_model_name(camera_model_from_id(id)), "test"), camera_model_from_id(id));
  }
}

// Every supported model against values hand-computed from COLMAP's definitions
// (src/colmap/sensor/models.h), both ways: img_from_cam gives the pixel, cam_from_img recovers the
// normalized point.
TEST(Camera, KnownValuesForEveryModelBothWays) {
  struct Case {
    Camera camera;
    Eigen::Vector2d normalized;
    Eigen::Vector2d pixel;
  };
  const std::vector<Case> cases = {
      // SIMPLE_PINHOLE f=500, c=(320, 240): (320 + 50, 240 - 100).
      {make(CameraModel::kSimplePinhole, {500, 320, 240}), {0.1, -0.2}, {370, 140}},
      // PINHOLE fx=500, fy=400.
      {make(CameraModel::kPinhole, {500, 400, 320, 240}), {0.1, -0.2}, {370, 160}},
      // SIMPLE_RADIAL k=-0.1, r2=0.05: factor 0.995.
      {make(CameraModel::kSimpleRadial, {500, 320, 240, -0.1}), {0.2, 0.1}, {419.5, 289.75}},
      // RADIAL k1=-0.1, k2=0.02, r2=0.05: factor 1 - 0.005 + 0.00005 = 0.99505.
      {make(CameraModel::kRadial, {500, 320, 240, -0.1, 0.02}), {0.2, 0.1}, {419.505, 289.7525}},
      // OPENCV k1=0.1, k2=-0.05, p1=0.001, p2=0.002 at (0.3, 0.4): r2=0.25, radial 0.021875,
      // du = 0.0065625 + 0.00024 + 0.00086, dv = 0.00875 + 0.00048 + 0.00057.
      {make(CameraModel::kOpenCV, {400, 300, 320, 240, 0.1, -0.05, 0.001, 0.002}), {0.3, 0.4}, {443.065, 362.94}},
      // FULL_OPENCV, the TUM freiburg1 camera at (0.2, -0.1): r2=0.05, radial 1.0108826625,
      // x_d = 0.2021765325 + 0.000216 + 0.000338, y_d = -0.10108826625 - 0.000104 - 0.000378.
      {make(CameraModel::kFullOpenCV, {517.3, 516.5, 318.6, 255.3, 0.2624, -0.9531, -0.0054, 0.0026, 1.1633, 0, 0, 0}),
       {0.2, -0.1},
       {318.6 + 517.3 * 0.2027305325, 255.3 - 516.5 * 0.10157026625}},
      // FULL_OPENCV rational terms k1..k6 at (0.3, 0.4): r2=0.25, r4=0.0625, r6=0.015625:
      // (1 + 0.025 + 0.000625 + 0.000015625) / (1 + 0.05 + 0.00125 + 0.00003125).
      {make(CameraModel::kFullOpenCV, {100, 100, 0, 0, 0.1, 0.01, 0, 0, 0.001, 0.2, 0.02, 0.002}),
       {0.3, 0.4},
       {30 * 1.025640625 / 1.05128125, 40 * 1.025640625 / 1.05128125}},
  };
  for (const Case& c : cases) {
    const std::string name = camera_model_name(c.camera.model);
    EXPECT_LT((c.camera.img_from_cam(c.normalized) - c.pixel).norm(), 1e-9) << name;
    EXPECT_LT((c.camera.cam_from_img(c.pixel) - c.normalized).norm(), 1e-9) << name;
  }
  // Spot check of the FULL_OPENCV pixel computed above, to the digits written out by hand.
  EXPECT_NEAR(cases[5].pixel.x(), 423.47250446, 1e-7);
  EXPECT_NEAR(cases[5].pixel.y(), 202.83895748, 1e-7);
}

// The text of a cameras.txt line without its id, as `lboost localize --camera` takes it.
TEST(Camera, FromTextReadsEveryModelAndWritesItBackExactly) {
  const Camera c = camera_from_text("SIMPLE_PINHOLE 640 480 525.5 319.5 239.5", "--camera");
  EXPECT_EQ(c.model, CameraModel::kSimplePinhole);
  EXPECT_EQ(c.width, 640);
  EXPECT_EQ(c.height, 480);
  EXPECT_EQ(c.params, (std::vector<double>{525.5, 319.5, 239.5}));
  // A line copied from cameras.txt (with its CAMERA_ID), tabs and spaces.
  const Camera o = camera_from_text("3  OPENCV\t320 240 230 230 160 120 -0.22 0.05 0.0008 -0.0005 ", "--camera");
  EXPECT_EQ(o.model, CameraModel::kOpenCV);
  EXPECT_EQ(o.params[5], 0.05);
  for (const std::string text : {"SIMPLE_PINHOLE 640 480 525.5 319.5 239.5", "PINHOLE 640 480 500 501 320 240",
                                 "SIMPLE_RADIAL 640 480 500 320 240 0.1", "RADIAL 640 480 500 320 240 0.1 -0.01",
                                 "OPENCV 320 240 230 230 160 120 -0.22 0.05 0.0008 -0.0005",
                                 "FULL_OPENCV 640 480 500 500 320 240 0.1 0.01 0 0 0.001 0.2 0.02 0.002"}) {
    const Camera a = camera_from_text(text, "--camera");
    const Camera b = camera_from_text(camera_to_text(a), "--camera");
    EXPECT_EQ(b.model, a.model) << text;
    EXPECT_EQ(b.params, a.params) << text;  // every double the same
    EXPECT_EQ(camera_to_text(b), camera_to_text(a)) << text;
  }
  EXPECT_EQ(camera_to_text(c), "SIMPLE_PINHOLE 640 480 525.5 319.5 239.5");
}

TEST(Camera, FromTextRefusesWithTheReason) {
  const auto error = [](const std::string& text) {
    try {
      camera_from_text(text, "--camera");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(error(""),
            "--camera: expected \"MODEL WIDTH HEIGHT PARAMS...\" (COLMAP cameras.txt, e.g. \"PINHOLE 640 480 "
            "fx fy cx cy\"), got ''");
  EXPECT_EQ(error("OPENCV_FISHEYE 640 480 1 2 3 4 5 6 7 8"),
            "--camera: unsupported camera model 'OPENCV_FISHEYE' (supported: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, "
            "RADIAL, OPENCV, FULL_OPENCV)");
  EXPECT_EQ(error("PINHOLE 640.5 480 500 500 320 240"),
            "--camera: WIDTH and HEIGHT must be whole numbers of pixels, got '640.5' and '480'");
  EXPECT_EQ(error("PINHOLE 640 -480 500 500 320 240"),
            "--camera: WIDTH and HEIGHT must be whole numbers of pixels, got '640' and '-480'");
  EXPECT_EQ(error("PINHOLE 0 480 500 500 320 240"), "--camera: image size must be positive, got 0x480");
  EXPECT_EQ(error("PINHOLE 640 480 500 500 320"), "--camera: camera model PINHOLE takes 4 parameters, got 3");
  EXPECT_EQ(error("PINHOLE 640 480 500 fy 320 240"), "--camera: camera parameter 1 is not a number: 'fy'");
  EXPECT_EQ(error("PINHOLE 640 480 500 nan 320 240"), "--camera: camera parameter 1 is not finite");
  EXPECT_EQ(error("PINHOLE 640 480 -500 500 320 240"), "--camera: focal length must be positive");
}

}  // namespace
}  // namespace lmb
