#include "train/world/world_model.h"

#include <set>

#include <gtest/gtest.h>

#include "common/error.h"

namespace lmb {
namespace {

TEST(WorldModelTest, PresetsAndChecks) {
  EXPECT_EQ(world_preset("tiny").map_frames, 30);
  EXPECT_EQ(world_preset("tiny").query_frames, 10);
  EXPECT_GT(world_preset("paper").length_m, world_preset("default").length_m);
  EXPECT_THROW(world_preset("huge"), Error);
  WorldOptions o = world_preset("tiny");
  o.map_frames = 0;
  EXPECT_THROW(o.check(), Error);
  o = world_preset("tiny");
  o.query_frames = 0;
  EXPECT_THROW(o.check(), Error);
  o = world_preset("tiny");
  o.length_m = 1.0;
  EXPECT_THROW(o.check(), Error);
  o = world_preset("tiny");
  o.preset = "bogus";
  EXPECT_THROW(build_world(o), Error);
  o = world_preset("tiny");
  o.door_share = 0.6;
  o.poster_share = 0.5;  // shares sum to more than 1
  EXPECT_THROW(o.check(), Error);
  o = world_preset("tiny");
  o.sign_share = -0.1;
  EXPECT_THROW(o.check(), Error);
  o = world_preset("tiny");
  o.pillar_bay_m = 1.0;
  EXPECT_THROW(o.check(), Error);
  o = world_preset("tiny");
  o.wall_stains_per_m = -1.0;
  EXPECT_THROW(o.check(), Error);
}

// The layout knobs do what they say: pillar bays, stain densities and the wall-slot shares.
TEST(WorldModelTest, LayoutKnobsShapeTheWorld) {
  WorldOptions o = world_preset("tiny");
  o.length_m = 16.0;
  o.pillar_bay_m = 3.0;  // pillars at x = 3, 6, 9, 12 on both walls (none within 1 m of the far end)
  o.wall_stains_per_m = 0.0;
  o.floor_stains_per_m = 0.0;
  const World bare = build_world(o);
  EXPECT_EQ(bare.summary.pillars, 8);
  EXPECT_EQ(bare.summary.stains, 0);
  o.door_share = 1.0;
  o.poster_share = 0.0;
  o.sign_share = 0.0;
  const World doors_only = build_world(o);
  EXPECT_GT(doors_only.summary.doors, bare.summary.doors);
  EXPECT_EQ(doors_only.summary.posters, 0);
  EXPECT_EQ(doors_only.summary.signs, 0);
  EXPECT_EQ(doors_only.summary.plates, doors_only.summary.doors);
}

// The default preset aliases more than tiny: more repeats of each door, pillar and poster design
// per unique cue (docs/evaluation.md "The rendered worlds and their aliasing": Hamming-NN precision@1 well below the
// control world's).
TEST(WorldModelTest, DefaultPresetRepeatsElementsMoreThanTiny) {
  const WorldOptions d = world_preset("default");
  const World w = build_world(d);
  std::set<int> door_textures;
  for (const Decal& door : w.doors) door_textures.insert(door.texture);
  EXPECT_EQ(door_textures.size(), 1u);
  EXPECT_GE(w.summary.doors, 6);
  EXPECT_GE(w.summary.pillars, 10);
  EXPECT_LE(w.summary.poster_textures, d.poster_designs);
  EXPECT_GE(w.summary.posters, 4 * d.poster_designs);
  const World t = build_world(world_preset("tiny"));
  const auto unique_per_repeat = [](const World& x) {
    return static_cast<double>(x.summary.stains + x.summary.signs) /
           (x.summary.doors + x.summary.posters + x.summary.pillars);
  };
  EXPECT_LT(unique_per_repeat(w), 0.5 * unique_per_repeat(t));
}

bool same_layout(const World& a, const World& b) {
  if (a.decals.size() != b.decals.size() || a.boxes.size() != b.boxes.size()) return false;
  for (size_t i = 0; i < a.decals.size(); ++i) {
    const Decal &x = a.decals[i], &y = b.decals[i];
    if (x.surface != y.surface || x.a0 != y.a0 || x.a1 != y.a1 || x.b0 != y.b0 || x.b1 != y.b1) return false;
  }
  for (size_t i = 0; i < a.boxes.size(); ++i) {
    if (a.boxes[i].lo != b.boxes[i].lo || a.boxes[i].hi != b.boxes[i].hi) return false;
  }
  return true;
}

TEST(WorldModelTest, AliasedWorldRepeatsTexturesControlWorldDoesNot) {
  WorldOptions o = world_preset("tiny");
  o.length_m = 16.0;
  const World aliased = build_world(o);
  o.non_aliased = true;
  const World control = build_world(o);
  ASSERT_GE(aliased.summary.doors, 3);
  ASSERT_GE(aliased.summary.posters, 3);
  EXPECT_TRUE(same_layout(aliased, control));

  std::set<int> door_textures_aliased, door_textures_control;
  for (const Decal& d : aliased.doors) door_textures_aliased.insert(d.texture);
  for (const Decal& d : control.doors) door_textures_control.insert(d.texture);
  EXPECT_EQ(door_textures_aliased.size(), 1u);
  EXPECT_EQ(door_textures_control.size(), control.doors.size());

  EXPECT_LE(aliased.summary.poster_textures, o.poster_designs);
  EXPECT_EQ(control.summary.poster_textures, control.summary.posters);
  EXPECT_EQ(std::set<int>(aliased.tile_texture.begin(), aliased.tile_texture.end()).size(), 1u);
  EXPECT_EQ(std::set<int>(control.tile_texture.begin(), control.tile_texture.end()).size(),
            control.tile_texture.size());
  // Pillars: one front texture in the aliased world.
  std::set<int> pillar_textures;
  for (const Box& b : aliased.boxes)
    if (b.hi.z() == aliased.height) pillar_textures.insert(b.texture_y);
  EXPECT_EQ(pillar_textures.size(), 1u);
  EXPECT_GT(control.textures.size(), aliased.textures.size());
}

TEST(WorldModelTest, DeterministicForASeedAndDifferentAcrossSeeds) {
  WorldOptions o = world_preset("tiny");
  const World a = build_world(o);
  const World b = build_world(o);
  EXPECT_TRUE(same_layout(a, b));
  ASSERT_EQ(a.textures.size(), b.textures.size());
  for (size_t i = 0; i < a.textures.size(); ++i) {
    EXPECT_EQ(cv::countNonZero(a.textures[i].level(0) != b.textures[i].level(0)), 0);
  }
  o.seed = 2;
  EXPECT_FALSE(same_layout(a, build_world(o)));
}

TEST(WorldModelTest, ElementsStayInsideTheCorridorAndDecalBinsCoverThem) {
  WorldOptions o = world_preset("default");
  const World w = build_world(o);
  for (const Decal& d : w.decals) {
    EXPECT_LT(d.a0, d.a1);
    EXPECT_LT(d.b0, d.b1);
    const bool end_wall = d.surface == Surface::kEndNear || d.surface == Surface::kEndFar;
    EXPECT_GE(d.a0, end_wall ? -w.width / 2 : 0.0);
    EXPECT_LE(d.a1, end_wall ? w.width / 2 : w.length);
  }
  for (size_t i = 0; i < w.decals.size(); ++i) {
    const Decal& d = w.decals[i];
    const double origin = (d.surface == Surface::kEndNear || d.surface == Surface::kEndFar) ? -w.width / 2 : 0.0;
    const int bin = static_cast<int>((0.5 * (d.a0 + d.a1) - origin) / w.bin_size);
    const auto& list = w.decal_bins[static_cast<int>(d.surface)][bin];
    EXPECT_NE(std::find(list.begin(), list.end(), static_cast<int>(i)), list.end());
  }
  for (const Box& b : w.boxes) {
    EXPECT_GE(b.lo.x(), 0.0);
    EXPECT_LE(b.hi.x(), w.length);
    EXPECT_GE(b.lo.y(), -w.width / 2);
    EXPECT_LE(b.hi.y(), w.width / 2);
    // Nothing reaches the walking lanes (|y| < 0.6).
    EXPECT_TRUE(b.hi.y() <= -0.6 || b.lo.y() >= 0.6);
  }
  EXPECT_GT(w.summary.doors, 5);
  EXPECT_GT(w.summary.plates, 5);
  EXPECT_GT(w.summary.stains, 3);
}

}  // namespace
}  // namespace lmb
