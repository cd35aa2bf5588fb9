// lmb_cross_case: writes a localization case (localize_case.h) from a map's query frames and a
// model, for another architecture to replay (scripts/cross_test.sh, ctest infer/cross_arch_test):
//   lmb_cross_case MAP.h5 MODEL.lbm OUT_DIR
// OUT_DIR gets model.lbm (a copy), frames.bin and expected.txt (this build's transcript).
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "common/io/map_h5.h"
#include "infer/localizer.h"
#include "infer/model.h"
#include "test/infer/cross_arch/localize_case.h"

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: %s MAP.h5 MODEL.lbm OUT_DIR\n", argv[0]);
    return 2;
  }
  try {
    const lmb::LandmarkMap map = lmb::read_map_h5(argv[1]);
    const std::filesystem::path out = argv[3];
    std::filesystem::create_directories(out);
    std::filesystem::copy_file(argv[2], out / "model.lbm", std::filesystem::copy_options::overwrite_existing);
    std::vector<lmb::test::CaseFrame> frames;
    for (const lmb::MapFrame& f : map.frames) {
      if (!f.is_query) continue;
      lmb::test::CaseFrame c;
      c.name = f.name;
      c.camera = map.cameras[f.camera];
      c.gravity_in_cam = f.gravity_in_cam;
      c.keypoints.assign(map.keypoints.begin() + f.first_keypoint,
                         map.keypoints.begin() + f.first_keypoint + f.num_keypoints);
      c.descriptors.assign(
          map.descriptor(f.first_keypoint),
          map.descriptor(f.first_keypoint) + static_cast<int64_t>(f.num_keypoints) * map.descriptor_bytes);
      frames.push_back(std::move(c));
    }
    LMB_CHECK(!frames.empty(), argv[1] << ": no query frames");
    lmb::test::write_case_frames((out / "frames.bin").string(), frames, static_cast<uint32_t>(map.descriptor_bytes));
    const std::shared_ptr<const lmb::Model> model = lmb::Model::load(out / "model.lbm");
    std::ofstream expected(out / "expected.txt");
    int poses = 0;
    size_t matches = 0;
    for (const auto& [setting, options] : lmb::test::case_settings()) {
      const lmb::Localizer localizer(model, options);
      for (const lmb::test::CaseFrame& f : frames) {
        const lmb::LocalizeResult r = localizer.localize(f.camera, f.keypoints, f.descriptors.data(), f.gravity_in_cam);
        expected << lmb::test::transcript(f.name, setting, r);
        poses += r.pose.success;
        matches += r.matches.matches.size();
      }
    }
    expected.close();
    LMB_CHECK(expected.good(), out / "expected.txt"
                                   << ": write failed");
    std::printf("lmb_cross_case: %zu query frames, %zu matches, %d poses -> %s\n", frames.size(), matches, poses,
                out.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lmb_cross_case: %s\n", e.what());
    return 1;
  }
}
