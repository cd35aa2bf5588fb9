// landmarkboost._io: map.h5 (common/io/map_h5.h) as a Python object whose columns are read-only
// numpy views into the map read by the C++ reader (same validation, same errors). A separate
// extension because it links HDF5, which landmarkboost._core must not pull into apps.
#include <memory>
#include <string>
#include <vector>

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "common/error.h"
#include "common/io/map_h5.h"
#include "common/landmark_map.h"
#include "numpy_util.h"

namespace lmb::python {
namespace {

using MapPtr = std::shared_ptr<LandmarkMap>;

// Landmark columns: strided views into the Landmark records.
template <class T>
py::array_t<T> landmark_column(const LandmarkMap& map, const T* first, py::handle owner) {
  return view<T>(first, {static_cast<py::ssize_t>(map.landmarks.size())}, {static_cast<py::ssize_t>(sizeof(Landmark))},
                 owner);
}

const Landmark& first_landmark(const LandmarkMap& map) {
  static const Landmark none;
  return map.landmarks.empty() ? none : map.landmarks.front();
}

void check_frame(const LandmarkMap& map, int64_t f) {
  if (f < 0 || f >= map.num_frames()) {
    throw py::index_error("frame " + std::to_string(f) + " out of range (the map has " +
                          std::to_string(map.num_frames()) + " frames)");
  }
}

}  // namespace
}  // namespace lmb::python

PYBIND11_MODULE(_io, m) {
  using namespace lmb;
  using namespace lmb::python;
  m.doc() = "LandmarkBoost map files (landmarkboost._io; use landmarkboost.io)";
  // Camera, Rigid3d and Error come from landmarkboost._core (imported here).
  translate_errors_to_core_error();

  py::class_<MapFrame>(m, "Frame", "One frame of a map: its image name, camera, pose, gravity and keypoint range.")
      .def_readonly("name", &MapFrame::name)
      .def_readonly("camera", &MapFrame::camera, "Index into Map.cameras.")
      .def_readonly("cam_from_world", &MapFrame::cam_from_world)
      .def_property_readonly(
          "gravity_in_cam", [](const MapFrame& f) { return Eigen::Vector3d(f.gravity_in_cam); },
          "Unit direction of gravity (down) in the camera frame.")
      .def_readonly("is_query", &MapFrame::is_query)
      .def_readonly("first_keypoint", &MapFrame::first_keypoint)
      .def_readonly("num_keypoints", &MapFrame::num_keypoints)
      .def("__repr__", [](const MapFrame& f) {
        return "<landmarkboost.io.Frame '" + f.name + "': " + (f.is_query ? "query" : "map") + ", " +
               std::to_string(f.num_keypoints) + " keypoints>";
      });

  py::class_<LandmarkMap, MapPtr>(m, "Map", R"(A landmark map (map.h5), read with read_map().
Columns are read-only numpy views into the map: keypoints (N, 4) float32 x, y, size, angle;
descriptors (N, descriptor_bytes) uint8; keypoint_landmark (N,) int64 (-1: none);
landmark_positions (L, 3); landmark_quality, landmark_mean_reprojection_error (L,) float32;
landmark_map_observations, landmark_query_observations (L,) int32. Frames keep their keypoints in
order: frame f's are rows frames[f].first_keypoint : + num_keypoints (frame_keypoints(f)).)")
      .def_readonly("detector", &LandmarkMap::detector)
      .def_readonly("descriptor_bytes", &LandmarkMap::descriptor_bytes)
      .def_readonly("cameras", &LandmarkMap::cameras)
      .def_readonly("frames", &LandmarkMap::frames)
      .def_property_readonly("num_frames", [](const LandmarkMap& map) { return map.frames.size(); })
      .def_property_readonly("num_keypoints", [](const LandmarkMap& map) { return map.keypoints.size(); })
      .def_property_readonly("num_landmarks", [](const LandmarkMap& map) { return map.landmarks.size(); })
      .def_property_readonly(
          "query_frames",
          [](const LandmarkMap& map) {
            std::vector<int32_t> q;
            for (frame_t f = 0; f < map.num_frames(); ++f) {
              if (map.frames[f].is_query) q.push_back(f);
            }
            return q;
          },
          "Indices of the query frames.")
      .def_property_readonly(
          "keypoints",
          [](py::object self) {
            const LandmarkMap& map = self.cast<const LandmarkMap&>();
            return view<float>(map.keypoints.empty() ? nullptr : &map.keypoints.front().x,
                               {static_cast<py::ssize_t>(map.keypoints.size()), 4},
                               {static_cast<py::ssize_t>(sizeof(Keypoint)), static_cast<py::ssize_t>(sizeof(float))},
                               self);
          })
      .def_property_readonly("descriptors",
                             [](py::object self) {
                               const LandmarkMap& map = self.cast<const LandmarkMap&>();
                               return view<uint8_t>(
                                   map.descriptors.data(),
                                   {static_cast<py::ssize_t>(map.keypoints.size()), map.descriptor_bytes},
                                   {map.descriptor_bytes, 1}, self);
                             })
      .def_property_readonly("keypoint_landmark",
                             [](py::object self) {
                               const LandmarkMap& map = self.cast<const LandmarkMap&>();
                               return view<landmark_t>(map.keypoint_landmark.data(), map.keypoint_landmark.size(),
                                                       self);
                             })
      .def_property_readonly(
          "landmark_positions",
          [](py::object self) {
            const LandmarkMap& map = self.cast<const LandmarkMap&>();
            return view<double>(
                first_landmark(map).position.data(), {static_cast<py::ssize_t>(map.landmarks.size()), 3},
                {static_cast<py::ssize_t>(sizeof(Landmark)), static_cast<py::ssize_t>(sizeof(double))}, self);
          })
      .def_property_readonly("landmark_quality",
                             [](py::object self) {
                               const LandmarkMap& map = self.cast<const LandmarkMap&>();
                               return landmark_column(map, &first_landmark(map).quality, self);
                             })
      .def_property_readonly("landmark_mean_reprojection_error",
                             [](py::object self) {
                               const LandmarkMap& map = self.cast<const LandmarkMap&>();
                               return landmark_column(map, &first_landmark(map).mean_reprojection_error, self);
                             })
      .def_property_readonly("landmark_map_observations",
                             [](py::object self) {
                               const LandmarkMap& map = self.cast<const LandmarkMap&>();
                               return landmark_column(map, &first_landmark(map).num_map_observations, self);
                             })
      .def_property_readonly("landmark_query_observations",
                             [](py::object self) {
                               const LandmarkMap& map = self.cast<const LandmarkMap&>();
                               return landmark_column(map, &first_landmark(map).num_query_observations, self);
                             })
      .def(
          "frame_keypoints",
          [](py::object self, int64_t f) {
            const LandmarkMap& map = self.cast<const LandmarkMap&>();
            check_frame(map, f);
            const MapFrame& fr = map.frames[f];
            const Keypoint* k = map.keypoints.data() + fr.first_keypoint;
            return view<float>(fr.num_keypoints ? &k->x : nullptr, {fr.num_keypoints, 4},
                               {static_cast<py::ssize_t>(sizeof(Keypoint)), static_cast<py::ssize_t>(sizeof(float))},
                               self);
          },
          py::arg("frame"), "(n, 4) float32 view of frame f's keypoints.")
      .def(
          "frame_descriptors",
          [](py::object self, int64_t f) {
            const LandmarkMap& map = self.cast<const LandmarkMap&>();
            check_frame(map, f);
            const MapFrame& fr = map.frames[f];
            return view<uint8_t>(fr.num_keypoints ? map.descriptor(fr.first_keypoint) : nullptr,
                                 {fr.num_keypoints, map.descriptor_bytes}, {map.descriptor_bytes, 1}, self);
          },
          py::arg("frame"), "(n, descriptor_bytes) uint8 view of frame f's descriptors.")
      .def(
          "frame_keypoint_landmarks",
          [](py::object self, int64_t f) {
            const LandmarkMap& map = self.cast<const LandmarkMap&>();
            check_frame(map, f);
            const MapFrame& fr = map.frames[f];
            return view<landmark_t>(map.keypoint_landmark.data() + fr.first_keypoint, fr.num_keypoints, self);
          },
          py::arg("frame"), "(n,) int64 view of frame f's keypoints' landmarks (-1: none).")
      .def("__repr__", [](const LandmarkMap& map) {
        int64_t queries = 0;
        for (const MapFrame& f : map.frames) queries += f.is_query;
        return "<landmarkboost.io.Map: " + std::to_string(map.frames.size() - queries) + " map + " +
               std::to_string(queries) + " query frames, " + std::to_string(map.keypoints.size()) + " keypoints, " +
               std::to_string(map.landmarks.size()) + " landmarks, " + map.detector + ">";
      });

  m.def(
      "read_map",
      [](const std::filesystem::path& path) {
        MapPtr map;
        {
          py::gil_scoped_release release;
          map = std::make_shared<LandmarkMap>(read_map_h5(path));
        }
        return map;
      },
      py::arg("path"), "Reads and validates map.h5; raises landmarkboost.Error naming the file, field and reason.");
}
