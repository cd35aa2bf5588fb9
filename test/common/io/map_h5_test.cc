#include "common/io/map_h5.h"

#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <functional>

#include <H5Cpp.h>
#include <gtest/gtest.h>

#include "common/error.h"
#include "common/random.h"
#include "test/common/io/test_maps.h"

namespace lmb {
namespace {

namespace fs = std::filesystem;

using test::random_map;

class MapH5Test : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("lmb_map_h5_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    H5::Exception::dontPrint();
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Writes a valid map, applies `edit` to the open file, and returns the error message of reading it.
  std::string error_after_edit(const std::function<void(H5::H5File&)>& edit) {
    const fs::path path = dir_ / "edited.h5";
    write_map_h5(random_map(3), path);
    {
      H5::H5File file(path.string(), H5F_ACC_RDWR);
      edit(file);
    }
    return read_error(path);
  }

  static std::string read_error(const fs::path& path) {
    try {
      read_map_h5(path);
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  }

  fs::path dir_;
};

void expect_equal(const LandmarkMap& a, const LandmarkMap& b) {
  EXPECT_EQ(a.detector, b.detector);
  EXPECT_EQ(a.descriptor_bytes, b.descriptor_bytes);
  ASSERT_EQ(a.cameras.size(), b.cameras.size());
  for (size_t c = 0; c < a.cameras.size(); ++c) {
    EXPECT_EQ(a.cameras[c].model, b.cameras[c].model);
    EXPECT_EQ(a.cameras[c].width, b.cameras[c].width);
    EXPECT_EQ(a.cameras[c].height, b.cameras[c].height);
    EXPECT_EQ(a.cameras[c].params, b.cameras[c].params);
  }
  ASSERT_EQ(a.sessions.size(), b.sessions.size());
  for (size_t s = 0; s < a.sessions.size(); ++s) {
    EXPECT_EQ(a.sessions[s].name, b.sessions[s].name);
    EXPECT_EQ(a.sessions[s].kind, b.sessions[s].kind);
  }
  ASSERT_EQ(a.frames.size(), b.frames.size());
  for (size_t f = 0; f < a.frames.size(); ++f) {
    const MapFrame& x = a.frames[f];
    const MapFrame& y = b.frames[f];
    EXPECT_EQ(x.name, y.name);
    EXPECT_EQ(x.camera, y.camera);
    EXPECT_EQ(x.session, y.session);
    EXPECT_EQ(x.cam_from_world.rotation.coeffs(), y.cam_from_world.rotation.coeffs());
    EXPECT_EQ(x.cam_from_world.translation, y.cam_from_world.translation);
    EXPECT_EQ(x.gravity_in_cam, y.gravity_in_cam);
    EXPECT_EQ(x.is_query, y.is_query);
    EXPECT_EQ(x.first_keypoint, y.first_keypoint);
    EXPECT_EQ(x.num_keypoints, y.num_keypoints);
  }
  ASSERT_EQ(a.keypoints.size(), b.keypoints.size());
  for (size_t k = 0; k < a.keypoints.size(); ++k) {
    EXPECT_EQ(a.keypoints[k].x, b.keypoints[k].x);
    EXPECT_EQ(a.keypoints[k].y, b.keypoints[k].y);
    EXPECT_EQ(a.keypoints[k].scale, b.keypoints[k].scale);
    EXPECT_EQ(a.keypoints[k].angle, b.keypoints[k].angle);
  }
  EXPECT_EQ(a.descriptors, b.descriptors);
  EXPECT_EQ(a.keypoint_landmark, b.keypoint_landmark);
  ASSERT_EQ(a.landmarks.size(), b.landmarks.size());
  for (size_t l = 0; l < a.landmarks.size(); ++l) {
    EXPECT_EQ(a.landmarks[l].position, b.landmarks[l].position);
    EXPECT_EQ(a.landmarks[l].quality, b.landmarks[l].quality);
    EXPECT_EQ(a.landmarks[l].mean_reprojection_error, b.landmarks[l].mean_reprojection_error);
    EXPECT_EQ(a.landmarks[l].num_map_observations, b.landmarks[l].num_map_observations);
    EXPECT_EQ(a.landmarks[l].num_query_observations, b.landmarks[l].num_query_observations);
  }
}

TEST_F(MapH5Test, RoundTripIsExact) {
  const LandmarkMap map = random_map(7);
  const fs::path path = dir_ / "map.h5";
  write_map_h5(map, path);
  expect_equal(map, read_map_h5(path));
  // No temporary file is left beside the output.
  int files = 0;
  for (const auto& entry : fs::directory_iterator(dir_)) files += entry.is_regular_file() ? 1 : 0;
  EXPECT_EQ(files, 1);
}

TEST_F(MapH5Test, SameMapGivesSameBytes) {
  const LandmarkMap map = random_map(11);
  write_map_h5(map, dir_ / "a.h5");
  write_map_h5(map, dir_ / "b.h5");
  auto bytes = [](const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  EXPECT_EQ(bytes(dir_ / "a.h5"), bytes(dir_ / "b.h5"));
}

TEST_F(MapH5Test, RoundTripOfAnEmptyMap) {
  LandmarkMap map;
  map.descriptor_bytes = 32;
  map.detector = "ORB";
  const fs::path path = dir_ / "empty.h5";
  write_map_h5(map, path);
  expect_equal(map, read_map_h5(path));
}

TEST_F(MapH5Test, RootAttributesAreSet) {
  const fs::path path = dir_ / "map.h5";
  write_map_h5(random_map(1), path);
  H5::H5File file(path.string(), H5F_ACC_RDONLY);
  std::string format;
  H5::Attribute attr = file.openAttribute("format");
  attr.read(attr.getStrType(), format);
  EXPECT_EQ(format, "landmarkboost-map");
  int version = 0;
  file.openAttribute("format_version").read(H5::PredType::NATIVE_INT, &version);
  EXPECT_EQ(version, 2);
}

// A format-1 file (written before sessions existed: no /sessions, no /frames/session) still loads:
// its map frames form the session "map", its query frames the session "query".
TEST_F(MapH5Test, VersionOneFilesLoadAsAMapAndAQuerySession) {
  const fs::path path = dir_ / "v1.h5";
  LandmarkMap map = random_map(4);
  write_map_h5(map, path);
  {
    H5::H5File file(path.string(), H5F_ACC_RDWR);
    file.unlink("/sessions");
    file.unlink("/frames/session");
    const int v = 1;
    file.openAttribute("format_version").write(H5::PredType::NATIVE_INT, &v);
  }
  const LandmarkMap read = read_map_h5(path);
  ASSERT_EQ(read.sessions.size(), 2u);
  EXPECT_EQ(read.sessions[0].name, "map");
  EXPECT_EQ(read.sessions[0].kind, SessionKind::kMap);
  EXPECT_EQ(read.sessions[1].name, "query");
  EXPECT_EQ(read.sessions[1].kind, SessionKind::kQuery);
  // random_map's frames 0-2 are map frames (sessions "map" and "map-2" in version 2), 3-4 queries.
  ASSERT_EQ(read.frames.size(), 5u);
  for (size_t f = 0; f < 5; ++f) EXPECT_EQ(read.frames[f].session, f < 3 ? 0 : 1) << f;
  // Everything else is the same map.
  map.sessions = read.sessions;
  for (size_t f = 0; f < 5; ++f) map.frames[f].session = read.frames[f].session;
  expect_equal(map, read);
  // A version-1 map without query frames has the one session "map".
  LandmarkMap no_query = random_map(4);
  no_query.sessions.clear();
  for (MapFrame& f : no_query.frames) f.is_query = false;
  for (Landmark& l : no_query.landmarks) {
    l.num_map_observations += l.num_query_observations;
    l.num_query_observations = 0;
  }
  assign_sessions_from_query_flags(&no_query);
  ASSERT_EQ(no_query.sessions.size(), 1u);
  for (const MapFrame& f : no_query.frames) EXPECT_EQ(f.session, 0);
  EXPECT_THROW(assign_sessions_from_query_flags(&no_query), Error);
}

TEST_F(MapH5Test, SessionErrorsNameTheField) {
  auto write_error = [&](const LandmarkMap& map) {
    try {
      write_map_h5(map, dir_ / "bad.h5");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  LandmarkMap map = random_map(2);
  map.frames[1].session = 3;
  EXPECT_NE(write_error(map).find("frames[1].session: 3"), std::string::npos) << write_error(map);
  map = random_map(2);
  map.frames[4].session = 0;  // a query frame in a map session
  EXPECT_NE(write_error(map).find("frames[4].is_query"), std::string::npos) << write_error(map);
  map = random_map(2);
  map.sessions[1].name = "map";
  EXPECT_NE(write_error(map).find("sessions[1].name: 'map' is also the name of sessions[0]"), std::string::npos)
      << write_error(map);
  map = random_map(2);
  map.sessions[2].name = "two words";
  EXPECT_NE(write_error(map).find("sessions[2].name"), std::string::npos) << write_error(map);
  map = random_map(2);
  map.sessions.clear();
  EXPECT_NE(write_error(map).find("sessions: none"), std::string::npos) << write_error(map);
  // Frames of an outside session observe no landmark.
  map = random_map(2);
  map.sessions[2].kind = SessionKind::kOutside;
  EXPECT_NE(write_error(map).find("outside session"), std::string::npos) << write_error(map);
  EXPECT_TRUE(fs::is_empty(dir_));

  const std::string kind = error_after_edit([](H5::H5File& f) {
    H5::DataSet ds = f.openDataSet("/sessions/kind");
    const uint8_t v[3] = {0, 7, 1};
    ds.write(v, H5::PredType::NATIVE_UINT8);
  });
  EXPECT_NE(kind.find("/sessions/kind[1]: 7"), std::string::npos) << kind;
  const std::string missing = error_after_edit([](H5::H5File& f) { f.unlink("/frames/session"); });
  EXPECT_NE(missing.find("/frames/session"), std::string::npos) << missing;
  EXPECT_NE(missing.find("missing"), std::string::npos) << missing;
}

TEST_F(MapH5Test, OverwritesAtomically) {
  const fs::path path = dir_ / "map.h5";
  write_map_h5(random_map(1), path);
  const LandmarkMap second = random_map(2);
  write_map_h5(second, path);
  expect_equal(second, read_map_h5(path));
}

TEST_F(MapH5Test, InvalidMapIsNotWritten) {
  LandmarkMap map = random_map(1);
  map.keypoint_landmark[3] = 99;  // out of range
  const fs::path path = dir_ / "bad.h5";
  EXPECT_THROW(write_map_h5(map, path), Error);
  EXPECT_FALSE(fs::exists(path));
  EXPECT_TRUE(fs::is_empty(dir_));
}

TEST_F(MapH5Test, MissingFile) {
  const std::string msg = read_error(dir_ / "nothing.h5");
  EXPECT_NE(msg.find("nothing.h5"), std::string::npos) << msg;
  EXPECT_NE(msg.find("no such file"), std::string::npos) << msg;
}

TEST_F(MapH5Test, NotAnHdf5File) {
  const fs::path path = dir_ / "text.h5";
  std::ofstream(path) << "this is not an HDF5 file, just some text long enough to be read\n";
  const std::string msg = read_error(path);
  EXPECT_NE(msg.find("text.h5"), std::string::npos) << msg;
  EXPECT_NE(msg.find("not an HDF5 file"), std::string::npos) << msg;
}

TEST_F(MapH5Test, TruncatedFilesFailWithOneError) {
  const fs::path path = dir_ / "map.h5";
  write_map_h5(random_map(5), path);
  const auto size = fs::file_size(path);
  std::vector<char> bytes(size);
  std::ifstream(path, std::ios::binary).read(bytes.data(), static_cast<std::streamsize>(size));
  for (double share : {0.0, 0.01, 0.1, 0.25, 0.5, 0.75, 0.9, 0.99}) {
    const size_t keep = static_cast<size_t>(share * static_cast<double>(size));
    const fs::path cut = dir_ / ("cut_" + std::to_string(keep) + ".h5");
    std::ofstream(cut, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(keep));
    const std::string msg = read_error(cut);
    EXPECT_FALSE(msg.empty()) << "truncated at " << keep << " of " << size << " bytes was accepted";
    EXPECT_NE(msg.find(cut.string()), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << "error spans lines: " << msg;
  }
}

TEST_F(MapH5Test, OtherFormat) {
  const std::string msg = error_after_edit([](H5::H5File& f) {
    f.removeAttr("format");
    H5::StrType type(H5::PredType::C_S1, H5T_VARIABLE);
    f.createAttribute("format", type, H5::DataSpace(H5S_SCALAR)).write(type, std::string("landmarkboost-checkpoint"));
  });
  EXPECT_NE(msg.find("'format'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("landmarkboost-checkpoint"), std::string::npos) << msg;
}

TEST_F(MapH5Test, HdfFileWithoutAttributes) {
  const fs::path path = dir_ / "plain.h5";
  {
    H5::H5File file(path.string(), H5F_ACC_TRUNC);
    file.createGroup("/data");
  }
  const std::string msg = read_error(path);
  EXPECT_NE(msg.find("attribute 'format'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("missing"), std::string::npos) << msg;
}

TEST_F(MapH5Test, OtherVersion) {
  const std::string msg = error_after_edit([](H5::H5File& f) {
    const int v = 3;
    f.openAttribute("format_version").write(H5::PredType::NATIVE_INT, &v);
  });
  EXPECT_NE(msg.find("format_version"), std::string::npos) << msg;
  EXPECT_NE(msg.find("version 3"), std::string::npos) << msg;
}

TEST_F(MapH5Test, InconsistentShapes) {
  const std::string msg = error_after_edit([](H5::H5File& f) {
    f.unlink("/keypoints/scale");
    const hsize_t dims[1] = {39};
    std::vector<float> v(39, 1.f);
    f.createDataSet("/keypoints/scale", H5::PredType::NATIVE_FLOAT, H5::DataSpace(1, dims))
        .write(v.data(), H5::PredType::NATIVE_FLOAT);
  });
  EXPECT_NE(msg.find("/keypoints/scale"), std::string::npos) << msg;
  EXPECT_NE(msg.find("39 rows, expected 40"), std::string::npos) << msg;

  const std::string cols = error_after_edit([](H5::H5File& f) {
    f.unlink("/keypoints/descriptors");
    const hsize_t dims[2] = {40, 32};
    std::vector<uint8_t> v(40 * 32, 0);
    f.createDataSet("/keypoints/descriptors", H5::PredType::NATIVE_UINT8, H5::DataSpace(2, dims))
        .write(v.data(), H5::PredType::NATIVE_UINT8);
  });
  EXPECT_NE(cols.find("32 columns, expected 64"), std::string::npos) << cols;

  const std::string missing = error_after_edit([](H5::H5File& f) { f.unlink("/landmarks/quality"); });
  EXPECT_NE(missing.find("/landmarks/quality"), std::string::npos) << missing;
  EXPECT_NE(missing.find("missing"), std::string::npos) << missing;

  const std::string type = error_after_edit([](H5::H5File& f) {
    f.unlink("/frames/camera");
    const hsize_t dims[1] = {5};
    std::vector<double> v(5, 0.0);
    f.createDataSet("/frames/camera", H5::PredType::NATIVE_DOUBLE, H5::DataSpace(1, dims))
        .write(v.data(), H5::PredType::NATIVE_DOUBLE);
  });
  EXPECT_NE(type.find("wrong element type"), std::string::npos) << type;
}

TEST_F(MapH5Test, IndicesOutOfRange) {
  const std::string landmark = error_after_edit([](H5::H5File& f) {
    H5::DataSet ds = f.openDataSet("/keypoints/landmark");
    std::vector<int64_t> v(40);
    ds.read(v.data(), H5::PredType::NATIVE_INT64);
    v[7] = 6;  // there are 6 landmarks: 0..5
    ds.write(v.data(), H5::PredType::NATIVE_INT64);
  });
  EXPECT_NE(landmark.find("keypoint_landmark[7]"), std::string::npos) << landmark;

  const std::string camera = error_after_edit([](H5::H5File& f) {
    H5::DataSet ds = f.openDataSet("/frames/camera");
    std::vector<int32_t> v(5);
    ds.read(v.data(), H5::PredType::NATIVE_INT32);
    v[2] = 2;
    ds.write(v.data(), H5::PredType::NATIVE_INT32);
  });
  EXPECT_NE(camera.find("frames[2].camera"), std::string::npos) << camera;

  const std::string range = error_after_edit([](H5::H5File& f) {
    H5::DataSet ds = f.openDataSet("/frames/first_keypoint");
    std::vector<int64_t> v(5);
    ds.read(v.data(), H5::PredType::NATIVE_INT64);
    v[1] = 9;
    ds.write(v.data(), H5::PredType::NATIVE_INT64);
  });
  EXPECT_NE(range.find("frames[1].first_keypoint"), std::string::npos) << range;

  const std::string model = error_after_edit([](H5::H5File& f) {
    H5::DataSet ds = f.openDataSet("/cameras/model");
    const int32_t v[2] = {4, 9};  // 9: a fisheye model this project does not represent
    ds.write(v, H5::PredType::NATIVE_INT32);
  });
  EXPECT_NE(model.find("/cameras/model[1]"), std::string::npos) << model;
}

TEST_F(MapH5Test, NonFiniteOrNonRotationValues) {
  const std::string nan = error_after_edit([](H5::H5File& f) {
    H5::DataSet ds = f.openDataSet("/landmarks/position");
    std::vector<double> v(18);
    ds.read(v.data(), H5::PredType::NATIVE_DOUBLE);
    v[4] = std::nan("");
    ds.write(v.data(), H5::PredType::NATIVE_DOUBLE);
  });
  EXPECT_NE(nan.find("landmarks[1].position"), std::string::npos) << nan;

  const std::string rotation = error_after_edit([](H5::H5File& f) {
    H5::DataSet ds = f.openDataSet("/frames/cam_from_world_q");
    std::vector<double> v(20);
    ds.read(v.data(), H5::PredType::NATIVE_DOUBLE);
    v[12] *= 1.5;
    ds.write(v.data(), H5::PredType::NATIVE_DOUBLE);
  });
  EXPECT_NE(rotation.find("frames[3].cam_from_world_q"), std::string::npos) << rotation;
  EXPECT_NE(rotation.find("not a rotation"), std::string::npos) << rotation;
}

TEST_F(MapH5Test, ObservationCountsMustMatch) {
  const std::string msg = error_after_edit([](H5::H5File& f) {
    H5::DataSet ds = f.openDataSet("/landmarks/num_map_observations");
    std::vector<int32_t> v(6);
    ds.read(v.data(), H5::PredType::NATIVE_INT32);
    v[0] += 1;
    ds.write(v.data(), H5::PredType::NATIVE_INT32);
  });
  EXPECT_NE(msg.find("landmarks[0].num_map_observations"), std::string::npos) << msg;
}

// Regression (found by test/fuzz/fuzz_map_h5; the input is test/common/io/data/
// fuzz_null_vlen_string.h5, a map.h5 with damaged bytes): libhdf5 returned a null pointer for the
// variable-length 'format' attribute and HDF5's C++ wrapper crashed in strlen.
TEST_F(MapH5Test, DamagedVariableLengthStringIsAnErrorNotACrash) {
  const char* source = std::getenv("LMB_SOURCE_DIR");
  ASSERT_NE(source, nullptr) << "LMB_SOURCE_DIR is not set (ctest sets it)";
  const fs::path path = fs::path(source) / "test/common/io/data/fuzz_null_vlen_string.h5";
  ASSERT_TRUE(fs::exists(path)) << path;
  const std::string msg = read_error(path);
  EXPECT_NE(msg.find(path.string() + ": "), std::string::npos) << msg;
  EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
}

TEST_F(MapH5Test, UnwritableFolderIsAnError) {
  EXPECT_THROW(write_map_h5(random_map(1), dir_ / "no" / "such" / "dir" / "map.h5"), Error);
}

}  // namespace
}  // namespace lmb
