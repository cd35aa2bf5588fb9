// landmarkboost._cv: the inference library's OpenCV front-end (infer/cv/feature_detection.h) on
// numpy images: keypoints and descriptors detected exactly as the mapper detects map images. A
// separate extension because it links OpenCV, which landmarkboost._core must not pull into apps.
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/detector_options.h"
#include "common/error.h"
#include "infer/cv/feature_detection.h"
#include "numpy_util.h"

PYBIND11_MODULE(_cv, m) {
  using namespace lmb;
  using namespace lmb::python;
  m.doc() = "LandmarkBoost's OpenCV front-end (landmarkboost._cv; use landmarkboost.cv)";
  translate_errors_to_core_error();

  m.def(
      "detect_features",
      [](const py::array& image, const std::string& channels, const std::string& detector, int max_keypoints,
         int brisk_threshold, int brisk_octaves) {
        if (image.dtype().kind() != 'u' || image.dtype().itemsize() != 1 || image.ndim() < 2 || image.ndim() > 3 ||
            (image.ndim() == 3 && image.shape(2) != 1 && image.shape(2) != 3 && image.shape(2) != 4)) {
          throw py::value_error(
              "detect_features: image: expected a uint8 array of shape (h, w), (h, w, 3) or "
              "(h, w, 4); got a " +
              describe(image));
        }
        if (channels != "RGB" && channels != "BGR") {
          throw py::value_error("detect_features: channels: '" + channels + "' (expected RGB or BGR)");
        }
        DetectorOptions options;
        options.detector = detector;
        options.max_keypoints = max_keypoints;
        options.brisk_threshold = brisk_threshold;
        options.brisk_octaves = brisk_octaves;
        options.check();
        // The pixels are read in place when the rows are contiguous (any row stride).
        auto pixels = py::array_t<uint8_t, py::array::forcecast>::ensure(image);
        const int c = image.ndim() == 3 ? static_cast<int>(image.shape(2)) : 1;
        if (pixels.strides(pixels.ndim() - 1) != 1 || (c > 1 && pixels.strides(1) != c)) {
          pixels = py::array_t<uint8_t, py::array::c_style | py::array::forcecast>::ensure(image);
        }
        const int rows = static_cast<int>(pixels.shape(0)), cols = static_cast<int>(pixels.shape(1));
        const cv::Mat mat(rows, cols, CV_8UC(c), const_cast<uint8_t*>(pixels.data()),
                          static_cast<size_t>(pixels.strides(0)));
        ImageFeatures f;
        {
          py::gil_scoped_release release;
          cv::Mat input = mat;
          // The C++ front-end takes OpenCV's BGR order; an RGB image is converted to grey here
          // with the same weights, so both orders give the same pixels.
          try {
            if (channels == "RGB" && c == 3) cv::cvtColor(mat, input, cv::COLOR_RGB2GRAY);
            if (channels == "RGB" && c == 4) cv::cvtColor(mat, input, cv::COLOR_RGBA2GRAY);
          } catch (const cv::Exception& e) {
            // landmarkboost.Error with one line, as detect_features raises for OpenCV's failures.
            throw Error("detect_features: OpenCV failed on a " + std::to_string(cols) + "x" + std::to_string(rows) +
                        " image: " + e.err);
          }
          f = detect_features(input, options);
        }
        const py::ssize_t n = static_cast<py::ssize_t>(f.keypoints.size());
        const py::ssize_t bytes = detector_descriptor_bytes(detector);
        std::vector<float> kp(static_cast<size_t>(n) * 4);
        for (py::ssize_t i = 0; i < n; ++i) {
          kp[4 * i] = f.keypoints[i].x;
          kp[4 * i + 1] = f.keypoints[i].y;
          kp[4 * i + 2] = f.keypoints[i].scale;
          kp[4 * i + 3] = f.keypoints[i].angle;
        }
        return py::make_tuple(take(std::move(kp), {n, 4}), take(std::move(f.descriptors), {n, bytes}),
                              take(std::move(f.responses), {n}));
      },
      py::arg("image"), py::arg("channels") = "RGB", py::arg("detector") = DetectorOptions().detector,
      py::arg("max_keypoints") = DetectorOptions().max_keypoints,
      py::arg("brisk_threshold") = DetectorOptions().brisk_threshold,
      py::arg("brisk_octaves") = DetectorOptions().brisk_octaves,
      "(keypoints (n, 4) float32, descriptors (n, bytes) uint8, responses (n,) float32) of an 8-bit image.");

  m.def(
      "read_image",
      [](const std::string& path) {
        // Checked first: OpenCV would print a warning of its own for a file it cannot open.
        std::error_code ec;
        if (!std::filesystem::is_regular_file(path, ec) || !std::ifstream(path).good()) {
          throw Error(path + ": cannot read the image: no such file, or not a readable file");
        }
        cv::Mat image;
        {
          py::gil_scoped_release release;
          // As `lboost map` reads its images (train/mapping/mapper.cc): OpenCV's decoder, grey.
          image = cv::imread(path, cv::IMREAD_GRAYSCALE);
        }
        if (image.empty()) throw Error(path + ": cannot read the image: not a format OpenCV decodes");
        if (!image.isContinuous()) image = image.clone();
        const py::ssize_t rows = image.rows, cols = image.cols;
        std::vector<uint8_t> pixels(image.data, image.data + rows * cols);
        return take(std::move(pixels), {rows, cols});
      },
      py::arg("path"), "The image file as an 8-bit grey (h, w) array, decoded as the mapper decodes it.");
}
