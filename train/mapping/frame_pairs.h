// Choice of the frame pairs the mapper matches. Two rules:
//   - by pose (select_frame_pairs): camera centres close, viewing directions similar, plus near
//     neighbours in capture order within a session. It pairs the map frames among themselves (and,
//     with an explicit pair distance, the query frames with them).
//   - by view overlap (select_overlap_pairs), for query frames: the scene points of a first map
//     (landmarks and the map frames that observe them) are projected into the query frame; its
//     partners are the map frames that observe most of the points it sees, from a similar direction
//     and distance, spread out in viewpoint so that near-duplicate video frames do not take every
//     slot. A dense video's pose rule links a query only to map frames centimetres away; the
//     overlap rule reaches the map frames that see the same surfaces from a metre or more.
// Query-query pairs are never chosen: query frames only need their link to the map. Frames of
// different map sessions pair like any others, so tracks join the sessions. Outside frames
// (recorded elsewhere) are never paired.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/camera.h"
#include "common/rigid3.h"

namespace lmb {

struct PairOptions {
  // Camera centres at most this far apart (world units). 0: automatic, 8 x the median distance
  // between map frames and their nearest map neighbour. Negative values are refused.
  double max_center_distance = 0.0;
  double max_view_angle_deg = 60.0;  // angle between the optical axes
  int max_pairs_per_frame = 20;      // the closest candidates per frame by distance and angle
  int sequence_neighbors = 2;        // map frames i and its next k map frames of the same session always pair
  void check() const;                // throws lmb::Error naming the field
};

struct PairFrame {
  Rigid3d cam_from_world;
  bool is_query = false;           // not a map frame (query or outside)
  int32_t session = 0;             // frames in capture order within a session
  bool outside = false;            // recorded where the map is not: never paired (implies is_query)
  const Camera* camera = nullptr;  // needed by select_overlap_pairs (query frames) only
};

// Returns pairs (i, j), i < j, sorted and unique. Deterministic.
std::vector<std::pair<int, int>> select_frame_pairs(const std::vector<PairFrame>& frames, const PairOptions& options);

// The distance used when max_center_distance <= 0 (see PairOptions); 0 with fewer than 2 map frames.
double automatic_pair_distance(const std::vector<PairFrame>& frames);

struct OverlapPairOptions {
  int partners_per_frame = 12;  // K: map-frame partners chosen per query frame
  // The partners of one query frame differ pairwise by at least this view change: the angle
  // between their optical axes plus their centre distance over the query's median scene depth (a
  // parallax angle), degrees. Keeps near-duplicate frames of a video from filling the K slots.
  double min_partner_separation_deg = 4.0;
  // A scene point counts for a pair when the two viewing rays to it meet at most at this angle
  // and its distances to the two centres differ by at most max_scale_change (either way).
  double max_ray_angle_deg = 40.0;
  double max_scale_change = 2.5;
  int min_shared_points = 12;  // a partner shares at least this many points with the query frame
  double min_depth = 0.2;      // scene points nearer than this (world units) are not seen
  double max_depth = 40.0;     // nor farther than this
  void check() const;          // throws lmb::Error naming the field
};

// Scene points of a first map: position (world) and the map frames (indices into the frames
// passed to select_overlap_pairs, never query frames) that observe each.
struct ScenePoints {
  std::vector<Eigen::Vector3d> position;
  std::vector<std::vector<int>> observers;  // per point, sorted, unique
};

// What select_overlap_pairs chose (the log's summary).
struct OverlapPairStats {
  int64_t pairs = 0;                   // overlap pairs, before joining with any other rule
  int query_frames_with = 0;           // query frames (not outside) given at least one partner
  int query_frames_without = 0;        // query frames (not outside) that no map frame overlaps
  double mean_partners = 0;            // per query frame with partners
  double median_partner_distance = 0;  // centre distance of query and partner, world units
  double p90_partner_distance = 0;
  double max_partner_distance = 0;
};

// Overlap pairs (i, j), i < j, sorted and unique: every query frame (not outside) is given up to
// options.partners_per_frame map-frame partners that share at least min_shared_points scene points
// with it, taken in decreasing order of shared points, skipping those closer than
// min_partner_separation_deg in view change to a partner already taken. Query frames need their
// camera set. Throws lmb::Error on an observer that is not a map frame. Deterministic.
std::vector<std::pair<int, int>> select_overlap_pairs(const std::vector<PairFrame>& frames, const ScenePoints& scene,
                                                      const OverlapPairOptions& options,
                                                      OverlapPairStats* stats = nullptr);

}  // namespace lmb
