// landmarkboost._core: the inference library (infer/localizer.h, infer/model.h, common/camera.h,
// infer/area_bundle.h, infer/bundle_localizer.h) for Python. Inputs are numpy arrays (descriptors are read in place
// when they are a C-contiguous uint8 array); results are read-only numpy views into the C++ result, kept alive by it.
// The GIL is released while a frame is localized, so Python threads localize in parallel.
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "common/camera.h"
#include "common/error.h"
#include "common/rigid3.h"
#include "common/types.h"
#include "common/vocabulary.h"
#include "infer/bundle_localizer.h"
#include "infer/c_api.h"
#include "infer/localizer.h"
#include "infer/model.h"
#include "infer/walk_confidence.h"
#include "numpy_util.h"

namespace lmb::python {
namespace {

static_assert(sizeof(Keypoint) == 4 * sizeof(float), "Keypoint must be 4 packed floats");

// Localize calls that ran with the GIL released (read by the tests through _calls_without_gil).
std::atomic<int64_t> calls_without_gil{0};

// ---- Argument values: Python numbers of the kind the C++ field holds ----------------------------
// (pybind11's own conversions would take any object with __bool__ for a bool, and fail with
// "Unable to cast Python instance" naming no argument for an integer out of the field's range.)

// "3.5 (float)" for error messages.
std::string value_and_type(const py::handle& v) {
  std::string r = py::repr(v).cast<std::string>();
  if (r.size() > 60) r = r.substr(0, 57) + "...";
  return r + " (" + py::type::of(v).attr("__name__").cast<std::string>() + ")";
}

bool is_bool(const py::handle& v) {
  return py::isinstance<py::bool_>(v) || py::isinstance(v, py::module_::import("numpy").attr("bool_"));
}

// True or False (or a numpy bool); `what` names the argument in the TypeError.
bool bool_from(const py::handle& v, const std::string& what) {
  if (!is_bool(v)) throw py::type_error(what + ": expected True or False; got " + value_and_type(v));
  return PyObject_IsTrue(v.ptr()) == 1;
}

// A real number: int, float or a numpy integer or floating scalar (not bool, not complex).
double real_from(const py::handle& v, const std::string& what) {
  if (is_bool(v) || !py::isinstance(v, py::module_::import("numbers").attr("Real"))) {
    throw py::type_error(what + ": expected a real number; got " + value_and_type(v));
  }
  const double d = PyFloat_AsDouble(v.ptr());
  if (d == -1.0 && PyErr_Occurred()) {
    PyErr_Clear();
    LMB_FAIL(what << " = " << value_and_type(v) << ": beyond the range of a double");
  }
  return d;
}

// An integer in lo..hi: int or a numpy integer (not bool, not float).
template <class T>
T integer_from(const py::handle& v, const std::string& what, T lo, T hi) {
  const std::string range = std::to_string(lo) + ".." + std::to_string(hi);
  if (is_bool(v) || !py::isinstance(v, py::module_::import("numbers").attr("Integral"))) {
    throw py::type_error(what + ": expected an integer in " + range + "; got " + value_and_type(v));
  }
  const py::int_ i(py::reinterpret_borrow<py::object>(v));
  LMB_CHECK(!(i < py::int_(lo)) && !(i > py::int_(hi)),
            what << " = " << py::repr(i).cast<std::string>() << ": must be an integer in " << range);
  return i.cast<T>();
}

template <class T, T kLo, T kHi>
T integer_in(const py::handle& v, const std::string& what) {
  return integer_from<T>(v, what, kLo, kHi);
}

// ---- Camera -------------------------------------------------------------------------------------

Camera make_camera(const py::object& model, int width, int height, const std::vector<double>& params) {
  Camera c;
  if (py::isinstance<py::str>(model)) {
    c.model = camera_model_from_name(model.cast<std::string>(), "Camera: model");
  } else if (!is_bool(model) && py::isinstance(model, py::module_::import("numbers").attr("Integral"))) {
    c.model = camera_model_from_id(integer_from<int>(model, "Camera: model", 0, std::numeric_limits<int>::max()));
  } else {
    throw py::type_error("Camera: model: expected a model name (str) or a COLMAP model id (int); got " +
                         value_and_type(model));
  }
  c.width = width;
  c.height = height;
  c.params = params;
  c.check("Camera");
  return c;
}

// ---- Options: flat Python names over the nested C++ struct --------------------------------------

struct OptionField {
  const char* name;
  py::object (*get)(const LocalizerOptions&);
  void (*set)(LocalizerOptions&, const py::object&);
  const char* doc;
};

// FROM: the conversion of the Python value (bool_from, real_from, integer_in<T, LO, HI>), whose
// errors name the option.
#define LMB_OPTION(NAME, MEMBER, FROM, DOC)                                           \
  OptionField {                                                                       \
    NAME, [](const LocalizerOptions& o) -> py::object { return py::cast(o.MEMBER); }, \
        [](LocalizerOptions& o, const py::object& v) {                                \
          o.MEMBER = FROM(v, std::string("LocalizerOptions: ") + NAME);               \
        },                                                                            \
        DOC                                                                           \
  }

constexpr int kIntMax = std::numeric_limits<int>::max();

// The integer ranges are those LocalizerOptions::check() accepts (pose_top_k is also <= top_k).
const std::vector<OptionField>& option_fields() {
  static const std::vector<OptionField> fields = {
      LMB_OPTION("top_k", classifier.top_k, (integer_in<int, 1, 1000000>), "Matches kept per keypoint (1..1000000)."),
      LMB_OPTION("use_inverted_file", classifier.use_inverted_file, bool_from,
                 "Score only the candidate classes of the keypoint's visual word."),
      LMB_OPTION("inverted_file_words", classifier.inverted_file_words, (integer_in<int, 1, kMaxVocabularyWords>),
                 "With the inverted file: the candidates of the keypoint's N nearest words (1 = its own)."),
      LMB_OPTION("min_margin", classifier.min_margin, real_from,
                 "A match's score must exceed the background's by more than this (-inf: no rejection)."),
      LMB_OPTION("min_score", classifier.min_score, real_from, "... and be at least this (-inf: no bound)."),
      LMB_OPTION("screening", classifier.screening, bool_from,
                 "Skip classes whose score bound cannot pass (same matches either way)."),
      LMB_OPTION("pose_top_k", pose_top_k, (integer_in<int, 1, 1000000>),
                 "Matches per keypoint given to RANSAC (1..top_k)."),
      LMB_OPTION("max_correspondences", max_correspondences, (integer_in<int, 0, kIntMax>),
                 "At most this many correspondences, the largest margins (0 = all)."),
      LMB_OPTION("ransac_iterations", pose.max_iterations, (integer_in<int, 1, kIntMax>),
                 "Most RANSAC hypotheses (>= 1)."),
      LMB_OPTION("max_reprojection_error_px", pose.max_reprojection_error_px, real_from,
                 "RANSAC inlier threshold, pixels."),
      LMB_OPTION("ransac_confidence", pose.success_probability, real_from,
                 "RANSAC's early stop: probability that no better-supported pose was missed, in (0, 1)."),
      LMB_OPTION("prosac", pose.progressive_sampling, bool_from,
                 "PROSAC: sample the matches of largest margin first (False = uniform sampling)."),
      LMB_OPTION(
          "seed", pose.seed, (integer_in<uint64_t, 0, static_cast<uint64_t>(std::numeric_limits<int64_t>::max())>),
          "RANSAC seed (0..2**63 - 1, as every seed of the project): equal seeds and inputs give equal results."),
      LMB_OPTION("min_inliers", pose.min_inliers, (integer_in<int, 4, kIntMax>), "Fewest inliers for a pose (>= 4)."),
      LMB_OPTION("refine", pose.refine, bool_from, "Non-linear refinement on the inliers."),
      LMB_OPTION("min_confidence", min_confidence, real_from,
                 "Probability a calibrated model's pose must reach (negative: the model's operating point)."),
  };
  return fields;
}
#undef LMB_OPTION

LocalizerOptions options_from_kwargs(const py::kwargs& kwargs) {
  LocalizerOptions o;
  for (const auto& [key, value] : kwargs) {
    const std::string name = key.cast<std::string>();
    bool found = false;
    for (const OptionField& f : option_fields()) {
      if (name == f.name) {
        f.set(o, py::reinterpret_borrow<py::object>(value));
        found = true;
      }
    }
    if (!found) {
      std::string names;
      for (const OptionField& f : option_fields()) names += std::string(names.empty() ? "" : ", ") + f.name;
      throw py::type_error("LocalizerOptions: unknown option '" + name + "' (options: " + names + ")");
    }
  }
  o.check();
  return o;
}

// ---- Inputs -------------------------------------------------------------------------------------

std::vector<Keypoint> keypoints_from(const py::array& a) {
  if (a.ndim() != 2 || a.shape(1) != 4) {
    throw py::value_error("localize: keypoints: expected an (n, 4) array of x, y, size, angle; got a " + describe(a));
  }
  const char kind = a.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u') {
    throw py::value_error("localize: keypoints: expected real numbers (a float or integer array); got a " +
                          describe(a));
  }
  // float32 C-contiguous arrays are read as they are; other dtypes and layouts are converted.
  const auto f = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(a);
  if (!f) throw py::value_error("localize: keypoints: cannot convert a " + describe(a) + " to float32");
  std::vector<Keypoint> keypoints(static_cast<size_t>(a.shape(0)));
  if (!keypoints.empty())
    std::memcpy(static_cast<void*>(keypoints.data()), f.data(), keypoints.size() * sizeof(Keypoint));
  // As float32 (values beyond its range are inf): what the library checks, and the angle, which it
  // does not read.
  for (size_t i = 0; i < keypoints.size(); ++i) {
    const Keypoint& k = keypoints[i];
    LMB_CHECK(std::isfinite(k.x) && std::isfinite(k.y) && std::isfinite(k.scale) && k.scale > 0.f &&
                  std::isfinite(k.angle) && std::abs(k.angle) <= 360.f,
              "localize: keypoints: row " << i << " (x, y, size, angle) = (" << k.x << ", " << k.y << ", " << k.scale
                                          << ", " << k.angle
                                          << "): x and y must be finite, size finite and > 0, angle degrees in "
                                             "[-360, 360] (-1: none)");
  }
  return keypoints;
}

// The descriptors as a C-contiguous uint8 array of shape (n, bytes): the caller's array itself
// when it is one (zero-copy), else a contiguous copy of it.
py::array_t<uint8_t> descriptors_from(const py::array& a, size_t n, int bytes) {
  if (a.dtype().kind() != 'u' || a.dtype().itemsize() != 1 || a.ndim() != 2 ||
      a.shape(0) != static_cast<py::ssize_t>(n) || a.shape(1) != bytes) {
    throw py::value_error("localize: descriptors: expected a uint8 array of shape (" + std::to_string(n) + ", " +
                          std::to_string(bytes) + ") (one row per keypoint, the model's descriptor bytes); got a " +
                          describe(a));
  }
  return py::array_t<uint8_t, py::array::c_style | py::array::forcecast>::ensure(a);
}

// ---- Results ------------------------------------------------------------------------------------

struct Result {
  LocalizeResult r;
};

// A bundle localization: the winning area's LocalizeResult (null without a pose) and the rest.
struct BundleResult {
  std::shared_ptr<Result> result;
  BundleLocalizeResult r;  // r.result moved into `result`
};

// A walk's verdict on a frame, as WalkTracker.update returns it.
py::dict verdict_dict(const WalkVerdict& v) {
  py::dict d;
  d["localized"] = v.localized;
  d["continues"] = v.continues;
  d["by_walk"] = v.by_walk;
  d["frame_confidence"] = v.frame_confidence;
  d["walk_confidence"] = v.walk_confidence;
  d["agrees"] = v.compared ? py::cast(v.agrees) : py::none();
  d["agreement_applies"] = v.agreement_applies;
  return d;
}

std::shared_ptr<BundleResult> bundle_result(BundleLocalizeResult&& r) {
  auto out = std::make_shared<BundleResult>();
  if (r.area >= 0) {
    out->result = std::make_shared<Result>();
    out->result->r = std::move(r.result);
  }
  out->r = std::move(r);
  return out;
}

AreaSearch area_search_from(const std::string& name) {
  if (name == "nearest_first") return AreaSearch::kNearestFirst;
  if (name == "all") return AreaSearch::kAll;
  if (name == "winners_view") return AreaSearch::kWinnersView;
  throw py::value_error("BundleLocalizer: search '" + name + "': expected 'nearest_first', 'winners_view' or 'all'");
}

AreaWinner area_winner_from(const std::string& name) {
  if (name == "support") return AreaWinner::kSupport;
  if (name == "inliers") return AreaWinner::kInliers;
  throw py::value_error("BundleLocalizer: winner '" + name + "': expected 'support' or 'inliers'");
}

std::optional<PositionPrior> prior_from(const py::object& prior) {
  if (prior.is_none()) return std::nullopt;
  if ((!py::isinstance<py::tuple>(prior) && !py::isinstance<py::list>(prior)) || py::len(prior) != 2) {
    throw py::value_error("prior: expected (position, radius) or None; got " + value_and_type(prior));
  }
  const auto t = prior.cast<py::sequence>();
  const py::array position = py::module_::import("numpy").attr("asarray")(t[0]);
  const char kind = position.dtype().kind();
  if ((kind != 'f' && kind != 'i' && kind != 'u') || position.ndim() != 1 || position.shape(0) != 3) {
    throw py::value_error("prior: position: expected 3 real numbers (x, y, z, world frame); got a " +
                          describe(position));
  }
  const auto xyz = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(position);
  PositionPrior p;
  p.position = Eigen::Vector3d(xyz.at(0), xyz.at(1), xyz.at(2));
  p.radius = real_from(py::object(t[1]), "prior: radius");
  return p;
}

// The frame of a bundle call: keypoints and descriptors checked against the bundle's length.
struct BundleFrameArgs {
  std::vector<Keypoint> keypoints;
  py::array_t<uint8_t> descriptors;
  const uint8_t* data() const { return keypoints.empty() ? nullptr : descriptors.data(); }
};

BundleFrameArgs bundle_frame(AreaBundle& bundle, const std::vector<int32_t>& ids, const py::array& keypoints,
                             const py::array& descriptors) {
  BundleFrameArgs f;
  f.keypoints = keypoints_from(keypoints);
  int bytes = bundle.descriptor_bytes(ids);
  if (bytes < 0) bytes = descriptors.ndim() == 2 ? static_cast<int>(descriptors.shape(1)) : 0;
  f.descriptors = descriptors_from(descriptors, f.keypoints.size(), bytes);
  return f;
}

template <class F>
auto field_view(const std::vector<ClassMatch>& m, const F* first_field, py::handle owner) {
  return view<F>(first_field, {static_cast<py::ssize_t>(m.size())}, {static_cast<py::ssize_t>(sizeof(ClassMatch))},
                 owner);
}

const ClassMatch& first_match(const Result& r) {
  static const ClassMatch none;
  return r.r.matches.matches.empty() ? none : r.r.matches.matches.front();
}

}  // namespace
}  // namespace lmb::python

PYBIND11_MODULE(_core, m) {
  using namespace lmb;
  using namespace lmb::python;
  m.doc() = "LandmarkBoost inference (landmarkboost._core; use the package landmarkboost)";
  m.attr("__version__") = lmb_version();
  static py::exception<Error> error(m, "Error", PyExc_RuntimeError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const Error& e) {
      raise_error(error.ptr(), e.what());
    }
  });
  m.def(
      "_calls_without_gil", [] { return calls_without_gil.load(); },
      "Localize calls that ran with the GIL released (tests).");

  // ---- Rigid3d ----
  py::class_<Rigid3d>(m, "Rigid3d", R"(A rigid transform a_from_b: x_a = rotation * x_b + translation.
rotation: unit quaternion (w, x, y, z); translation: 3 values. Poses are cam_from_world (camera
frame x right, y down, z forward).)")
      .def(py::init([](const Eigen::Vector4d& wxyz, const Eigen::Vector3d& t) {
             const Eigen::Quaterniond q(wxyz[0], wxyz[1], wxyz[2], wxyz[3]);
             LMB_CHECK(std::abs(q.norm() - 1.0) < 1e-6,
                       "Rigid3d: rotation must be a unit quaternion (w, x, y, z); its norm is " << q.norm());
             return Rigid3d(q.normalized(), t);
           }),
           py::arg("rotation") = Eigen::Vector4d(1, 0, 0, 0), py::arg("translation") = Eigen::Vector3d::Zero())
      .def_static(
          "from_matrix",
          [](const Eigen::Matrix<double, 3, 4>& m34) {
            const Eigen::Matrix3d r = m34.leftCols<3>();
            LMB_CHECK((r * r.transpose() - Eigen::Matrix3d::Identity()).norm() < 1e-6 && r.determinant() > 0,
                      "Rigid3d.from_matrix: the left 3x3 block is not a rotation");
            return Rigid3d(Eigen::Quaterniond(r).normalized(), m34.col(3));
          },
          py::arg("matrix"), "From a 3x4 matrix [R | t].")
      .def_property_readonly(
          "rotation",
          [](const Rigid3d& p) {
            return Eigen::Vector4d(p.rotation.w(), p.rotation.x(), p.rotation.y(), p.rotation.z());
          },
          "Unit quaternion (w, x, y, z).")
      .def_property_readonly("translation", [](const Rigid3d& p) { return Eigen::Vector3d(p.translation); })
      .def(
          "matrix",
          [](const Rigid3d& p) {
            Eigen::Matrix<double, 3, 4> m34;
            m34 << p.rotation.toRotationMatrix(), p.translation;
            return m34;
          },
          "The 3x4 matrix [R | t].")
      .def("center", &Rigid3d::center, "For a cam_from_world pose: the camera centre in the world.")
      .def("inverse", &Rigid3d::inverse)
      .def("__mul__", [](const Rigid3d& a, const Rigid3d& b) { return a * b; })
      .def("__mul__", [](const Rigid3d& a, const Eigen::Vector3d& x) { return Eigen::Vector3d(a * x); })
      .def("__repr__", [](const Rigid3d& p) {
        return "Rigid3d(rotation=[" + std::to_string(p.rotation.w()) + ", " + std::to_string(p.rotation.x()) + ", " +
               std::to_string(p.rotation.y()) + ", " + std::to_string(p.rotation.z()) + "], translation=[" +
               std::to_string(p.translation.x()) + ", " + std::to_string(p.translation.y()) + ", " +
               std::to_string(p.translation.z()) + "])";
      });

  // ---- Camera ----
  py::class_<Camera>(m, "Camera", R"(A camera with COLMAP's models and parameter orders:
SIMPLE_PINHOLE f, cx, cy; PINHOLE fx, fy, cx, cy; SIMPLE_RADIAL f, cx, cy, k; RADIAL f, cx, cy, k1, k2;
OPENCV fx, fy, cx, cy, k1, k2, p1, p2; FULL_OPENCV fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6.
Pixels follow COLMAP's convention: the centre of the top-left pixel is (0.5, 0.5).)")
      .def(py::init(&make_camera), py::arg("model"), py::arg("width"), py::arg("height"), py::arg("params"))
      .def_property_readonly("model", [](const Camera& c) { return camera_model_name(c.model); })
      .def_property_readonly("width", [](const Camera& c) { return c.width; })
      .def_property_readonly("height", [](const Camera& c) { return c.height; })
      .def_property_readonly("params", [](const Camera& c) { return c.params; })
      .def(
          "project",
          [](const Camera& c, const py::array_t<double, py::array::c_style | py::array::forcecast>& points) {
            if (points.ndim() != 2 || points.shape(1) != 3) {
              throw py::value_error("Camera.project: points: expected an (n, 3) array; got a " + describe(points));
            }
            const py::ssize_t n = points.shape(0);
            std::vector<double> out(static_cast<size_t>(2 * n));
            for (py::ssize_t i = 0; i < n; ++i) {
              Eigen::Vector2d pixel(std::nan(""), std::nan(""));
              if (!c.project(Eigen::Vector3d(points.at(i, 0), points.at(i, 1), points.at(i, 2)), &pixel)) {
                pixel.setConstant(std::nan(""));
              }
              out[2 * i] = pixel.x();
              out[2 * i + 1] = pixel.y();
            }
            return take(std::move(out), {n, 2});
          },
          py::arg("points_in_cam"),
          "(n, 2) pixels (COLMAP's convention, distortion applied) of (n, 3) points in the camera frame; nan behind.")
      .def("__eq__",
           [](const Camera& a, const Camera& b) {
             return a.model == b.model && a.width == b.width && a.height == b.height && a.params == b.params;
           })
      .def("__repr__", [](const Camera& c) {
        std::string s = "Camera('" + camera_model_name(c.model) + "', " + std::to_string(c.width) + ", " +
                        std::to_string(c.height) + ", [";
        for (size_t i = 0; i < c.params.size(); ++i)
          s += (i ? ", " : "") + py::repr(py::float_(c.params[i])).cast<std::string>();
        return s + "])";
      });

  // ---- Options ----
  py::class_<LocalizerOptions> opts(m, "LocalizerOptions", R"(Localization options; keyword arguments set them:
LocalizerOptions(top_k=5, pose_top_k=2, seed=1). The defaults are those of `lboost localize`.)");
  opts.def(py::init([](const py::kwargs& kwargs) { return options_from_kwargs(kwargs); }))
      .def("check", &LocalizerOptions::check, "Raises landmarkboost.Error naming an invalid field.")
      .def("__repr__", [](const LocalizerOptions& o) {
        std::string s = "LocalizerOptions(";
        bool first = true;
        for (const OptionField& f : option_fields()) {
          s += (first ? "" : ", ") + std::string(f.name) + "=" + py::repr(f.get(o)).cast<std::string>();
          first = false;
        }
        return s + ")";
      });
  for (const OptionField& f : option_fields()) {
    const OptionField* field = &f;
    opts.def_property(
        f.name, [field](const LocalizerOptions& o) { return field->get(o); },
        [field](LocalizerOptions& o, const py::object& v) { field->set(o, v); }, f.doc);
  }

  // ---- Model ----
  py::class_<Model, std::shared_ptr<Model>>(m, "Model", "An inference model (model.lbm), immutable.")
      .def_static(
          "load", [](const std::filesystem::path& path) { return std::const_pointer_cast<Model>(Model::load(path)); },
          py::arg("path"), "Reads model.lbm; raises landmarkboost.Error naming the file and reason.")
      .def_static(
          "from_bytes",
          [](const py::bytes& b) {
            const std::string s = b;
            return std::const_pointer_cast<Model>(
                Model::from_bytes(reinterpret_cast<const uint8_t*>(s.data()), s.size(), "bytes"));
          },
          py::arg("data"), "The same from the file's bytes.")
      .def_property_readonly("num_classes", &Model::num_classes, "Landmark classes C (class C is the background).")
      .def_property_readonly("descriptor_bytes", &Model::descriptor_bytes)
      .def_property_readonly("num_words", &Model::num_words)
      .def_property_readonly("detector", [](const Model& mo) { return mo.data().detector; })
      .def_property_readonly("num_stumps", [](const Model& mo) { return mo.data().stumps.size(); })
      .def_property_readonly("calibrated", &Model::calibrated,
                             "Whether the model holds a pose calibration (False: trusted by inlier count alone).")
      .def_property_readonly(
          "walk_calibrated", [](const Model& mo) { return mo.walk_calibration().has_value(); },
          "Whether the model holds a walk calibration (WalkTracker then reports poses that continue a walk).")
      .def_property_readonly(
          "confidence_threshold", [](const Model& mo) { return mo.calibrated() ? mo.calibration().threshold : -1.0; },
          "The calibrated model's operating point (-1 when not calibrated).")
      .def_property_readonly(
          "class_landmarks",
          [](py::object self) {
            const Model& mo = self.cast<const Model&>();
            return view<landmark_t>(mo.data().class_landmark.data(), mo.data().class_landmark.size(), self);
          },
          "(C,) int64: the map landmark id of each class.")
      .def_property_readonly(
          "class_positions",
          [](py::object self) {
            const Model& mo = self.cast<const Model&>();
            const auto& p = mo.data().class_position;
            static_assert(sizeof(Eigen::Vector3d) == 3 * sizeof(double));
            return view<double>(
                p.empty() ? nullptr : p.front().data(), {static_cast<py::ssize_t>(p.size()), 3},
                {static_cast<py::ssize_t>(sizeof(Eigen::Vector3d)), static_cast<py::ssize_t>(sizeof(double))}, self);
          },
          "(C, 3) float64: each class's landmark position, world frame.")
      .def("__repr__", [](const Model& mo) {
        return "<landmarkboost.Model: " + std::to_string(mo.num_classes()) + " classes, " +
               std::to_string(mo.data().stumps.size()) + " stumps, " + std::to_string(mo.num_words()) + " words, " +
               mo.data().detector + " " + std::to_string(mo.descriptor_bytes()) + "-byte descriptors>";
      });

  // ---- Result ----
  py::class_<Result, std::shared_ptr<Result>>(m, "LocalizeResult", R"(One frame's localization.
success (the frame is localized: a pose of at least min_inliers inliers and, when the model is
calibrated, confidence >= confidence_threshold), pose_found (the pose alone), calibrated, confidence
(P(pose within 20 cm / 5 deg), -1 when the model is not calibrated), confidence_threshold,
cam_from_world (Rigid3d), num_inliers, iterations; the ranked matches of every keypoint in
CSR form (keypoint k's matches, best first, are rows match_begin[k]:match_begin[k+1] of the match_*
arrays); the correspondences given to RANSAC (indices into the keypoints and into the matches) and
their inlier mask; timings in milliseconds. Arrays are read-only views into this result.)")
      .def_property_readonly("success", [](const Result& r) { return r.r.localized; })
      .def_property_readonly("pose_found", [](const Result& r) { return r.r.pose.success; })
      .def_property_readonly("calibrated", [](const Result& r) { return r.r.calibrated; })
      .def_property_readonly("confidence", [](const Result& r) { return r.r.confidence; })
      .def_property_readonly("confidence_threshold", [](const Result& r) { return r.r.confidence_threshold; })
      .def_property_readonly("cam_from_world", [](const Result& r) { return r.r.pose.cam_from_world; })
      .def_property_readonly("num_inliers", [](const Result& r) { return r.r.pose.num_inliers; })
      .def_property_readonly("iterations", [](const Result& r) { return r.r.pose.iterations; })
      .def_property_readonly(
          "ransac",
          [](const Result& r) {
            const RansacStats& st = r.r.pose.stats;
            py::dict d;
            d["iterations"] = st.iterations;
            d["models"] = st.models;
            d["refinements"] = st.refinements;
            d["num_data"] = st.num_data;
            d["inlier_ratio"] = st.inlier_ratio;
            d["score"] = st.score;
            d["subset_size"] = st.subset_size;
            d["stop_subset"] = st.stop_subset;
            d["runner_up_inliers"] = st.runner_up_inliers;
            d["runner_up_shared"] = st.runner_up_shared;
            return d;
          },
          "dict: the LO-RANSAC statistics (infer/ransac.h RansacStats): samples, models, refinements, "
          "correspondences, inlier ratio, MSAC score, PROSAC subsets, the runner-up's support.")
      .def_property_readonly("num_keypoints", [](const Result& r) { return r.r.matches.num_keypoints(); })
      .def_property_readonly("num_matches", [](const Result& r) { return r.r.matches.matches.size(); })
      .def_property_readonly(
          "match_begin",
          [](py::object self) {
            const Result& r = self.cast<const Result&>();
            return view<int32_t>(r.r.matches.begin.data(), r.r.matches.begin.size(), self);
          },
          "(n + 1,) int32: keypoint k's matches are rows match_begin[k]:match_begin[k + 1].")
      .def_property_readonly(
          "match_keypoint",
          [](const Result& r) {
            std::vector<int32_t> k(r.r.matches.matches.size());
            for (int32_t i = 0; i < r.r.matches.num_keypoints(); ++i) {
              for (int32_t j = r.r.matches.begin[i]; j < r.r.matches.begin[i + 1]; ++j) k[j] = i;
            }
            return take(std::move(k), {static_cast<py::ssize_t>(r.r.matches.matches.size())});
          },
          "(m,) int32: the keypoint of each match.")
      .def_property_readonly(
          "match_rank",
          [](const Result& r) {
            std::vector<int32_t> k(r.r.matches.matches.size());
            for (int32_t i = 0; i < r.r.matches.num_keypoints(); ++i) {
              for (int32_t j = r.r.matches.begin[i]; j < r.r.matches.begin[i + 1]; ++j) k[j] = j - r.r.matches.begin[i];
            }
            return take(std::move(k), {static_cast<py::ssize_t>(r.r.matches.matches.size())});
          },
          "(m,) int32: 0 for a keypoint's best match, 1 for the next...")
      .def_property_readonly(
          "match_class",
          [](py::object self) {
            const Result& r = self.cast<const Result&>();
            return field_view(r.r.matches.matches, &first_match(r).cls, self);
          },
          "(m,) int32: the landmark class.")
      .def_property_readonly(
          "match_landmark",
          [](py::object self) {
            const Result& r = self.cast<const Result&>();
            return field_view(r.r.matches.matches, &first_match(r).landmark, self);
          },
          "(m,) int64: the map landmark id.")
      .def_property_readonly(
          "match_score",
          [](py::object self) {
            const Result& r = self.cast<const Result&>();
            return field_view(r.r.matches.matches, &first_match(r).score, self);
          },
          "(m,) float64: the class score.")
      .def_property_readonly(
          "match_background_score",
          [](py::object self) {
            const Result& r = self.cast<const Result&>();
            return field_view(r.r.matches.matches, &first_match(r).background_score, self);
          },
          "(m,) float64: the keypoint's background score.")
      .def_property_readonly(
          "correspondence_keypoint",
          [](py::object self) {
            const Result& r = self.cast<const Result&>();
            return view<int32_t>(r.r.correspondence_keypoint.data(), r.r.correspondence_keypoint.size(), self);
          },
          "(c,) int32: the keypoint of each correspondence given to RANSAC.")
      .def_property_readonly(
          "correspondence_match",
          [](py::object self) {
            const Result& r = self.cast<const Result&>();
            return view<int32_t>(r.r.correspondence_match.data(), r.r.correspondence_match.size(), self);
          },
          "(c,) int32: the match (row of the match_* arrays) of each correspondence.")
      .def_property_readonly(
          "inlier_mask",
          [](py::object self) {
            const Result& r = self.cast<const Result&>();
            return bool_view(r.r.pose.inlier_mask, self);
          },
          "(c,) bool: the correspondences that are inliers of cam_from_world.")
      .def_property_readonly("timings_ms",
                             [](const Result& r) {
                               py::dict d;
                               d["words"] = r.r.timings.words_ms;
                               d["embedding"] = r.r.timings.embedding_ms;
                               d["classification"] = r.r.timings.classification_ms;
                               d["pose"] = r.r.timings.pose_ms;
                               d["total"] = r.r.timings.total_ms;
                               return d;
                             })
      .def("__repr__", [](const Result& r) {
        return std::string("<landmarkboost.LocalizeResult: ") + (r.r.localized ? "localized, " : "not localized, ") +
               std::to_string(r.r.pose.num_inliers) + " inliers of " + std::to_string(r.r.correspondence_match.size()) +
               " correspondences, " + std::to_string(r.r.matches.matches.size()) + " matches of " +
               std::to_string(r.r.matches.num_keypoints()) + " keypoints>";
      });

  // ---- Localizer ----
  py::class_<Localizer>(m, "Localizer", R"(Localizes frames with a model: Localizer(model, options=None).
One Localizer may serve any number of threads at once; localize() releases the GIL.)")
      .def(py::init([](std::shared_ptr<Model> model, const LocalizerOptions* options) {
             return Localizer(std::move(model), options ? *options : LocalizerOptions());
           }),
           py::arg("model"), py::arg("options") = nullptr)
      .def_property_readonly("model",
                             [](const Localizer& l) { return std::const_pointer_cast<Model>(l.shared_model()); })
      .def_property_readonly("options", [](const Localizer& l) { return l.options(); })
      .def(
          "localize",
          [](const Localizer& l, const Camera& camera, const py::array& keypoints, const py::array& descriptors,
             const Eigen::Vector3d& gravity_in_cam, const LocalizerOptions* options) {
            const std::vector<Keypoint> kps = keypoints_from(keypoints);
            const py::array_t<uint8_t> desc = descriptors_from(descriptors, kps.size(), l.model().descriptor_bytes());
            const uint8_t* d = kps.empty() ? nullptr : desc.data();
            auto result = std::make_shared<Result>();
            {
              py::gil_scoped_release release;
              if (!PyGILState_Check()) ++calls_without_gil;
              result->r = l.localize(camera, kps, d, gravity_in_cam, options ? *options : l.options());
            }
            return result;
          },
          py::arg("camera"), py::arg("keypoints"), py::arg("descriptors"), py::arg("gravity_in_cam"),
          py::arg("options") = nullptr,
          R"(Localizes one frame.
camera: Camera; keypoints: (n, 4) array of x, y, size, angle (pixels in COLMAP's convention: OpenCV's
KeyPoint.pt + 0.5; size = the detector's diameter, pixels; angle in degrees or -1); descriptors:
(n, model.descriptor_bytes) uint8, read in place when C-contiguous; gravity_in_cam: the direction
of gravity (down) in the camera frame (x right, y down, z forward), any length; options: per-call
LocalizerOptions (default: the Localizer's). Raises landmarkboost.Error for invalid input; not
finding a pose is result.success False.)");

  // ---- Walks ----
  py::class_<WalkTracker>(m, "WalkTracker", R"(Judges the frames of one walk (a camera localized frame after frame):
WalkTracker(model). A frame's pose is reported when the model's pose calibration reports it, or when it
continues the walk (a small step from the last trusted pose) by the model's walk calibration
(model.walk_calibrated), and, when that calibration has an agreement, it agrees with the pose of the frame
before. One tracker follows one camera.)")
      .def(py::init([](const std::shared_ptr<Model>& model) {
             if (!model->calibrated()) {
               LMB_FAIL("WalkTracker: the model has no pose calibration (lboost export or lboost calibrate)");
             }
             return WalkTracker(model->calibration(), model->walk_calibration());
           }),
           py::arg("model"))
      .def(
          "update",
          [](WalkTracker& t, const Result& r) {
            return verdict_dict(t.update(r.r.pose.success, r.r.pose.cam_from_world, r.r.evidence));
          },
          py::arg("result"),
          R"(Judges the walk's next frame (a LocalizeResult of Localizer.localize) and returns a dict: localized (the
answer to act on), continues (the walk rule judged it: a trusted pose at most a few frames back), by_walk
(reported by the walk rule alone), frame_confidence, walk_confidence, agrees (None when the pose was not
compared with an earlier frame's, else whether it agreed), agreement_applies (the walk has moved like the map's
walks so far: a pose that disagrees is then not reported).)")
      .def("reset", &WalkTracker::reset, "Forgets the last trusted and estimated poses.")
      .def_property_readonly("last_trusted", [](const WalkTracker& t) -> py::object {
        if (!t.last_trusted()) return py::none();
        return py::cast(*t.last_trusted());
      });

  // ---- Area bundles ----
  py::class_<AreaBundle, std::shared_ptr<AreaBundle>>(m, "AreaBundle", R"(A bundle of area models (bundle.txt of
`lboost bundle`, docs/areas.md): opening reads the index only; an area's model is read on its first
use (its size and CRC-32 checked) and freed by release_except() or the cache limits. A missing or
damaged area fails alone; the others still load.)")
      .def_static("open", &AreaBundle::open, py::arg("path"),
                  "Reads and checks bundle.txt; raises landmarkboost.Error naming the line.")
      .def_property_readonly("num_areas", [](const AreaBundle& b) { return b.areas().size(); })
      .def_property_readonly("reach", &AreaBundle::reach, "Metres: how far the map's cameras see.")
      .def_property_readonly("map_fingerprint", &AreaBundle::map_fingerprint,
                             "Fingerprint of the map the areas split (0: an index of version 1 or 2 records none).")
      .def_property_readonly("index_path", &AreaBundle::index_path)
      .def_property_readonly(
          "areas",
          [](const AreaBundle& b) {
            py::list out;
            for (const BundleArea& a : b.areas()) {
              py::dict d;
              d["id"] = a.id;
              d["file"] = a.file;
              d["bytes"] = a.bytes;
              d["crc32"] = a.crc32;
              d["landmarks"] = a.landmarks;
              d["first_landmark"] = a.first_landmark;
              d["last_landmark"] = a.last_landmark;
              d["classes"] = a.classes;
              d["cell_lo"] = a.cell_lo;
              d["cell_hi"] = a.cell_hi;
              out.append(d);
            }
            return out;
          },
          "list of dict: id, file, bytes, crc32, landmarks, first_landmark, last_landmark, classes (the model's "
          "classes fingerprint; 0 in indexes of version 1 and 2), cell_lo, cell_hi (world frame; ends may be +-inf).")
      .def(
          "select",
          [](const AreaBundle& b, const py::object& prior) {
            const std::optional<PositionPrior> p = prior_from(prior);
            return b.select(p ? &*p : nullptr);
          },
          py::arg("prior") = py::none(),
          "Ids of the areas a prior (position, radius) selects (cell within radius + reach), ascending; every id "
          "for None.")
      .def(
          "model", [](AreaBundle& b, int32_t id) { return std::const_pointer_cast<Model>(b.model(id)); }, py::arg("id"),
          "Area id's model, read on first use; raises landmarkboost.Error naming the area.")
      .def("visible_landmarks", &AreaBundle::visible_landmarks, py::arg("id"), py::arg("camera"),
           py::arg("cam_from_world"),
           "How many of area id's landmarks (a sample of at most 1,024) a camera at cam_from_world sees: in front, "
           "within the reach, inside the image; what track() orders the areas by.")
      .def("loaded", &AreaBundle::loaded, py::arg("id"))
      .def("release_except", &AreaBundle::release_except, py::arg("keep"), "Frees the models of the areas not in keep.")
      .def(
          "set_cache_limits",
          [](AreaBundle& b, int64_t max_areas, uint64_t max_bytes) {
            b.set_cache_limits({max_areas, max_bytes});
          },
          py::arg("max_areas") = 0, py::arg("max_bytes") = 0,
          "At most max_areas areas / max_bytes model bytes loaded (0 = no limit), least recently used freed first.")
      .def_property_readonly("loaded_ids", &AreaBundle::loaded_ids)
      .def_property_readonly("loaded_bytes", &AreaBundle::loaded_bytes)
      .def_property_readonly("loads", &AreaBundle::loads, "Reads of area models from their files.")
      .def_property_readonly("calibrated", &AreaBundle::calibrated,
                             "Whether the index holds the bundle's pose calibration (lboost bundle --map).")
      .def_property_readonly(
          "descriptor_bytes", [](const AreaBundle& b) { return b.descriptor_bytes(); },
          "The areas' descriptor length (-1 until an area has loaded).")
      .def("__repr__", [](const AreaBundle& b) {
        return "<landmarkboost.AreaBundle: " + std::to_string(b.areas().size()) + " areas, " +
               std::to_string(b.loaded_ids().size()) + " loaded, " + b.index_path().string() + ">";
      });

  py::class_<BundleResult, std::shared_ptr<BundleResult>>(m, "BundleLocalizeResult", R"(One frame localized in a bundle.
area (the winning area, -1 without a pose), pose_found (area >= 0), result (the winning area's
LocalizeResult, None without a pose: result.success says whether its calibration trusts the pose),
cam_from_world (None without a pose), scored (the areas scored, in order), inliers and support (per
scored area: its pose's inliers, and the frame's keypoints it explains with every scored area's
matches), rival_support (the most keypoints another area's pose explains with matches the winner
does not), localized (the answer to act on: with a calibrated bundle confidence >=
confidence_threshold, else the winning area's own result.success), calibrated, confidence, errors (one line per selected area that could not be loaded), selected, loaded,
prior_used, total_ms.)")
      .def_property_readonly("area", [](const BundleResult& b) { return b.r.area; })
      .def_property_readonly("pose_found", [](const BundleResult& b) { return b.r.area >= 0; })
      .def_property_readonly("result", [](const BundleResult& b) { return b.result; })
      .def_property_readonly("cam_from_world",
                             [](const BundleResult& b) -> std::optional<Rigid3d> {
                               if (!b.result) return std::nullopt;
                               return b.result->r.pose.cam_from_world;
                             })
      .def_property_readonly("scored", [](const BundleResult& b) { return b.r.scored; })
      .def_property_readonly("inliers", [](const BundleResult& b) { return b.r.inliers; })
      .def_property_readonly("support", [](const BundleResult& b) { return b.r.support; })
      .def_property_readonly("rival_support", [](const BundleResult& b) { return b.r.rival_support; })
      .def_property_readonly("localized", [](const BundleResult& b) { return b.r.localized; })
      .def_property_readonly("calibrated", [](const BundleResult& b) { return b.r.calibrated; })
      .def_property_readonly("confidence", [](const BundleResult& b) { return b.r.confidence; })
      .def_property_readonly("confidence_threshold", [](const BundleResult& b) { return b.r.confidence_threshold; })
      .def_property_readonly("errors", [](const BundleResult& b) { return b.r.errors; })
      .def_property_readonly("selected", [](const BundleResult& b) { return b.r.selected; })
      .def_property_readonly("loaded", [](const BundleResult& b) { return b.r.loaded; })
      .def_property_readonly("prior_used", [](const BundleResult& b) { return b.r.prior_used; })
      .def_property_readonly(
          "tracked", [](const BundleResult& b) { return b.r.tracked; },
          "track(): the pose passed the motion gate of the last tracked pose.")
      .def_property_readonly(
          "frame_localized", [](const BundleResult& b) { return b.r.frame_localized; },
          "The frame rule's verdict alone (localized is the walk's in track() with a walk-calibrated bundle).")
      .def_property_readonly(
          "walk",
          [](const BundleResult& b) -> py::object {
            if (!b.r.walk_judged) return py::none();
            return verdict_dict(b.r.walk);
          },
          "track() with a walk-calibrated bundle: the walk's verdict, the dict WalkTracker.update returns; else "
          "None.")
      .def_property_readonly("total_ms", [](const BundleResult& b) { return b.r.total_ms; })
      .def("__repr__", [](const BundleResult& b) {
        return "<landmarkboost.BundleLocalizeResult: area " + std::to_string(b.r.area) + ", " +
               std::to_string(b.r.scored.size()) + " of " + std::to_string(b.r.selected) + " selected areas scored, " +
               std::to_string(b.r.errors.size()) + " errors>";
      });

  py::class_<BundleLocalizer>(m, "BundleLocalizer", R"(Localizes frames in an AreaBundle:
BundleLocalizer(bundle, options=None, search="nearest_first", winner="support", tracking_radius=1.0,
relocalize_without_prior=True, area_threads=1, tracking_areas=2). search: "nearest_first" (with a prior, the nearest area whose
calibrated pose is localized wins and the rest are not scored), "winners_view" (the same stops, the areas after
the first pose in the order of how much of the current winning pose's view they see) or "all"; winner: "support" (the pose
that explains most keypoints with every scored area's matches) or "inliers"; area_threads: areas
localized at once, each on its own thread (the same result); tracking_radius: how far the camera
moves between two tracked frames (the motion gate); tracking_areas: areas scored before the gate judges
the winning pose. localize() releases
the GIL and may serve several threads; track() keeps the last pose (one camera, one thread).)")
      .def(py::init([](std::shared_ptr<AreaBundle> bundle, const LocalizerOptions* options, const std::string& search,
                       const std::string& winner, double tracking_radius, bool relocalize_without_prior,
                       int area_threads, int tracking_areas) {
             BundleLocalizerOptions o;
             if (options) o.localizer = *options;
             o.search = area_search_from(search);
             o.winner = area_winner_from(winner);
             o.tracking_radius = tracking_radius;
             o.relocalize_without_prior = relocalize_without_prior;
             o.area_threads = area_threads;
             o.tracking_areas = tracking_areas;
             return BundleLocalizer(std::move(bundle), o);
           }),
           py::arg("bundle"), py::arg("options") = nullptr, py::arg("search") = "nearest_first",
           py::arg("winner") = "support", py::arg("tracking_radius") = 1.0, py::arg("relocalize_without_prior") = true,
           py::arg("area_threads") = 1, py::arg("tracking_areas") = 2)
      .def_property_readonly("bundle", [](const BundleLocalizer& l) { return l.shared_bundle(); })
      .def(
          "localize",
          [](const BundleLocalizer& l, const Camera& camera, const py::array& keypoints, const py::array& descriptors,
             const Eigen::Vector3d& gravity_in_cam, const py::object& prior) {
            const std::optional<PositionPrior> p = prior_from(prior);
            const BundleFrameArgs f =
                bundle_frame(l.bundle(), l.bundle().select(p ? &*p : nullptr), keypoints, descriptors);
            BundleLocalizeResult r;
            {
              py::gil_scoped_release release;
              r = l.localize(camera, f.keypoints, f.data(), gravity_in_cam, p ? &*p : nullptr);
            }
            return bundle_result(std::move(r));
          },
          py::arg("camera"), py::arg("keypoints"), py::arg("descriptors"), py::arg("gravity_in_cam"),
          py::arg("prior") = py::none(),
          R"(Localizes one frame in the areas prior = (position, radius) selects (every area for None).
Arguments as Localizer.localize; descriptors: (n, bundle.descriptor_bytes) uint8. Raises
landmarkboost.Error for invalid input; areas that cannot be loaded are listed in result.errors.)")
      .def(
          "track",
          [](BundleLocalizer& l, const Camera& camera, const py::array& keypoints, const py::array& descriptors,
             const Eigen::Vector3d& gravity_in_cam, const py::object& prior) {
            const std::optional<PositionPrior> p = prior_from(prior);
            const BundleFrameArgs f = bundle_frame(l.bundle(), l.bundle().select(nullptr), keypoints, descriptors);
            BundleLocalizeResult r;
            {
              py::gil_scoped_release release;
              r = l.track(camera, f.keypoints, f.data(), gravity_in_cam, p ? &*p : nullptr);
            }
            return bundle_result(std::move(r));
          },
          py::arg("camera"), py::arg("keypoints"), py::arg("descriptors"), py::arg("gravity_in_cam"),
          py::arg("prior") = py::none(),
          R"(Tracking: the areas near the last tracked pose, those that see most of its view first, until the
pose that wins among tracking_areas or more of them lies within tracking_radius of it (result.tracked); the
first frame, and a frame those areas do not localize, are relocalized (result.prior_used False) in every area,
or in those prior = (position, radius) selects, nearest first (e.g. a GPS fix).)")
      .def("reset_tracking", &BundleLocalizer::reset_tracking)
      .def_property(
          "last_position", [](const BundleLocalizer& l) { return l.last_position(); },
          [](BundleLocalizer& l, const std::optional<Eigen::Vector3d>& p) { l.set_last_position(p); },
          "The last tracked camera centre (world frame), or None; setting it forgets the last orientation.")
      .def_property(
          "last_pose", [](const BundleLocalizer& l) { return l.last_pose(); },
          [](BundleLocalizer& l, const std::optional<Rigid3d>& p) { l.set_last_pose(p); },
          "The last tracked pose (cam_from_world), or None; set it from odometry to predict the next frame's view.");
}
