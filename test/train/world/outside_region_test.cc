// The outside corridor (WorldOptions::outside_frames): a second corridor of the same building,
// rendered away from the mapped one. Its repeated elements use the mapped corridor's textures
// (realistic aliasing), its layout and unique items differ, its recorded poses lie
// kOutsideOffsetY metres away, and every pixel of its frames sees its own corridor (depth within
// the corridor), so no landmark of the map (all inside the mapped corridor) can be in view.
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "train/world/renderer.h"
#include "train/world/trajectory.h"
#include "train/world/world_model.h"

namespace lmb {
namespace {

TEST(OutsideRegionTest, SameTexturesOtherLayoutRenderedAwayFromTheMap) {
  WorldOptions o = world_preset("tiny");
  o.outside_frames = 4;
  o.image_scale = 0.25;
  o.supersampling = 1;
  const World mapped = build_world(o);
  WorldOptions oo = o;
  oo.region = 1;
  const World outside = build_world(oo);
  // The mapped corridor is the one of a world without an outside session (unchanged content).
  WorldOptions plain = o;
  plain.outside_frames = 0;
  const World before = build_world(plain);
  ASSERT_EQ(before.decals.size(), mapped.decals.size());
  for (size_t i = 0; i < before.decals.size(); ++i) EXPECT_EQ(before.decals[i].a0, mapped.decals[i].a0);
  // Same door texture (the aliased type), other door positions.
  ASSERT_FALSE(mapped.doors.empty());
  ASSERT_FALSE(outside.doors.empty());
  const Texture& door_a = mapped.textures[mapped.doors.front().texture];
  const Texture& door_b = outside.textures[outside.doors.front().texture];
  ASSERT_EQ(door_a.level(0).size(), door_b.level(0).size());
  EXPECT_EQ(cv::norm(door_a.level(0), door_b.level(0), cv::NORM_INF), 0.0);
  bool layout_differs = mapped.doors.size() != outside.doors.size();
  for (size_t i = 0; !layout_differs && i < mapped.doors.size(); ++i) {
    layout_differs = mapped.doors[i].a0 != outside.doors[i].a0 || mapped.doors[i].surface != outside.doors[i].surface;
  }
  EXPECT_TRUE(layout_differs);

  const Session s = make_outside_session(outside, o.outside_frames);
  EXPECT_EQ(s.kind, SessionKind::kOutside);
  EXPECT_EQ(s.name, "outside");
  ASSERT_EQ(s.cam_from_world.size(), 4u);
  const Camera camera = world_camera(o.image_scale);
  const RayTable rays(camera, o.supersampling);
  for (size_t i = 0; i < s.cam_from_world.size(); ++i) {
    // Recorded: kOutsideOffsetY along +y; every point of the mapped corridor is at least
    // kOutsideOffsetY - width away from the camera.
    const Eigen::Vector3d centre = s.recorded_cam_from_world(i).inverse().translation;
    const Eigen::Vector3d local = s.cam_from_world[i].inverse().translation;
    EXPECT_NEAR(centre.y() - local.y(), kOutsideOffsetY, 1e-9);
    EXPECT_NEAR((centre - local).norm(), kOutsideOffsetY, 1e-9);
    // Every pixel hits the outside corridor within its own extent.
    const RenderedFrame f = render_frame(outside, rays, s.cam_from_world[i], s.lighting, s.frame_key_base | i, 1);
    double max_depth_mm = 0;
    int invalid = 0;
    for (int y = 0; y < f.depth_mm.rows; ++y) {
      for (int x = 0; x < f.depth_mm.cols; ++x) {
        const uint16_t d = f.depth_mm.at<uint16_t>(y, x);
        invalid += d == 0;
        max_depth_mm = std::max(max_depth_mm, static_cast<double>(d));
      }
    }
    EXPECT_EQ(invalid, 0) << "frame " << i;
    const double diagonal_mm =
        1000.0 * std::sqrt(o.length_m * o.length_m + o.width_m * o.width_m + o.height_m * o.height_m);
    EXPECT_LE(max_depth_mm, diagonal_mm) << "frame " << i;
    EXPECT_LT(max_depth_mm, 1000.0 * (kOutsideOffsetY - o.width_m)) << "frame " << i;
  }
}

}  // namespace
}  // namespace lmb
