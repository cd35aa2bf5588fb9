#include "train/mapping/tracks.h"

#include <algorithm>

#include <gtest/gtest.h>

#include "common/error.h"
#include "common/random.h"

namespace lmb {
namespace {

TEST(BuildTracks, ChainsJoinAcrossFrames) {
  // Keypoints 0,1 in frame 0; 2,3 in frame 1; 4,5 in frame 2.
  const std::vector<frame_t> frame = {0, 0, 1, 1, 2, 2};
  const auto tracks = build_tracks(frame, {{0, 2, 10}, {2, 4, 12}, {1, 5, 3}});
  ASSERT_EQ(tracks.size(), 2u);
  EXPECT_EQ(tracks[0], (std::vector<int64_t>{0, 2, 4}));
  EXPECT_EQ(tracks[1], (std::vector<int64_t>{1, 5}));
}

TEST(BuildTracks, NeverTwoKeypointsOfOneFrame) {
  const std::vector<frame_t> frame = {0, 0, 1, 2};
  // 0-2 (best), 1-3, then 2-3 would join {0,2} with {1,3}: both hold a frame-0 keypoint.
  const auto tracks = build_tracks(frame, {{2, 3, 30}, {0, 2, 5}, {1, 3, 6}});
  ASSERT_EQ(tracks.size(), 2u);
  EXPECT_EQ(tracks[0], (std::vector<int64_t>{0, 2}));
  EXPECT_EQ(tracks[1], (std::vector<int64_t>{1, 3}));
  // A match inside one frame is ignored.
  EXPECT_TRUE(build_tracks(frame, {{0, 1, 1}}).empty());
}

TEST(BuildTracks, BetterMatchWinsTheConflict) {
  const std::vector<frame_t> frame = {0, 1, 1};
  // Keypoint 0 matches both 1 and 2 of frame 1: only the closer descriptor joins.
  auto tracks = build_tracks(frame, {{0, 1, 40}, {0, 2, 20}});
  ASSERT_EQ(tracks.size(), 1u);
  EXPECT_EQ(tracks[0], (std::vector<int64_t>{0, 2}));
}

TEST(BuildTracks, IndependentOfMatchOrderAndAgreesWithBruteForce) {
  Rng rng(5);
  const int num_frames = 12, per_frame = 30;
  std::vector<frame_t> frame;
  for (int f = 0; f < num_frames; ++f) frame.insert(frame.end(), per_frame, f);
  std::vector<KeypointMatch> matches;
  for (int i = 0; i < 600; ++i) {
    matches.push_back({static_cast<int64_t>(rng.below(frame.size())), static_cast<int64_t>(rng.below(frame.size())),
                       static_cast<int32_t>(rng.below(100))});
  }
  const auto reference = build_tracks(frame, matches);
  for (int trial = 0; trial < 3; ++trial) {
    rng.shuffle(matches);
    EXPECT_EQ(build_tracks(frame, matches), reference);
  }
  // Brute force: every track holds distinct frames, tracks are disjoint, sorted.
  std::vector<int> seen(frame.size(), 0);
  for (const auto& t : reference) {
    ASSERT_GE(t.size(), 2u);
    EXPECT_TRUE(std::is_sorted(t.begin(), t.end()));
    std::vector<frame_t> frames;
    for (int64_t k : t) {
      frames.push_back(frame[k]);
      EXPECT_EQ(seen[k]++, 0);
    }
    std::sort(frames.begin(), frames.end());
    EXPECT_EQ(std::adjacent_find(frames.begin(), frames.end()), frames.end());
  }
  // Every accepted-in-order match whose ends lie in different tracks must have been a conflict:
  // the union of the two tracks would hold one frame twice.
  std::vector<int> track_of(frame.size(), -1);
  for (size_t t = 0; t < reference.size(); ++t) {
    for (int64_t k : reference[t]) track_of[k] = static_cast<int>(t);
  }
  for (const auto& m : matches) {
    if (frame[m.a] == frame[m.b] || (track_of[m.a] >= 0 && track_of[m.a] == track_of[m.b])) continue;
    // Not joined: a conflict must exist between the final tracks (or singletons).
    std::vector<frame_t> fa, fb;
    if (track_of[m.a] >= 0)
      for (int64_t k : reference[track_of[m.a]]) fa.push_back(frame[k]);
    else
      fa.push_back(frame[m.a]);
    if (track_of[m.b] >= 0)
      for (int64_t k : reference[track_of[m.b]]) fb.push_back(frame[k]);
    else
      fb.push_back(frame[m.b]);
    bool conflict = false;
    for (frame_t x : fa) conflict |= std::find(fb.begin(), fb.end(), x) != fb.end();
    EXPECT_TRUE(conflict) << "match " << m.a << "-" << m.b << " was dropped without a conflict";
  }
}

TEST(BuildTracks, RejectsOutOfRangeIndices) { EXPECT_THROW(build_tracks({0, 1}, {{0, 2, 1}}), Error); }

}  // namespace
}  // namespace lmb
