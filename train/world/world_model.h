// The rendered world's geometry: one straight indoor corridor in metres, world frame x along the
// corridor (0..length), y across it (-width/2..width/2), z up (floor z = 0, ceiling z = height);
// gravity is -z. Surfaces carry a base pattern (floor tiles, ceiling panels, plain walls with a
// skirting and a rail) plus rectangular decals (doors, posters, room plates, signs, stains, lamps);
// pillars and a few unique objects are axis-aligned boxes.
//
// Self-similarity: in the default (aliased) world every door, pillar, floor tile, ceiling panel and
// lamp uses one texture of its type and posters come from a few designs; room-number plates, signs,
// stains and objects are unique. In the control world (non_aliased) every element instance gets its
// own texture seed while the geometry, layout and trajectories stay identical.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "train/world/texture.h"

namespace lmb {

inline constexpr int kMaxMapSessions = 4;
inline constexpr int kMaxQuerySessions = 3;
// Where the outside corridor lies: this far along +y from the mapped one (world frame, metres).
inline constexpr double kOutsideOffsetY = 1000.0;

struct WorldOptions {
  std::string preset = "default";
  uint64_t seed = 1;
  bool non_aliased = false;
  double length_m = 16.0;  // corridor length
  double width_m = 2.4;    // corridor width
  double height_m = 2.7;   // ceiling height
  int map_frames = 40;     // over all map sessions (split evenly)
  int query_frames = 16;   // per query session
  int map_sessions = 1;    // 1..kMaxMapSessions (train/world/trajectory.h)
  int query_sessions = 1;  // 1..kMaxQuerySessions
  // Frames of the "outside" session (0 = none; 0..1000000): a second corridor of the same
  // building that no map session sees, kOutsideOffsetY metres away: the same sizes and the same
  // textures of every repeated element (doors, posters, pillars, tiles, lamps), so its aliasing
  // is the mapped corridor's, but its own layout, unique items (plates, signs, stains, objects)
  // and walk (the first query session's style). Written as a session of kind outside.
  int outside_frames = 0;
  // The corridor build_world builds: 0 the mapped one, 1 the outside one (write_world sets it).
  int region = 0;
  int poster_designs = 4;          // distinct poster designs of the aliased world
  double pillar_bay_m = 4.0;       // pillar spacing along the corridor
  double door_share = 0.45;        // share of wall slots that get a door (+ room plate)
  double poster_share = 0.35;      // share of wall slots that get a poster
  double sign_share = 0.12;        // share of wall slots that get a unique sign (the rest stay plain)
  double wall_stains_per_m = 0.7;  // unique stains per metre on each side wall
  double floor_stains_per_m = 0.5;
  double image_scale = 1.0;  // image size relative to 640 x 480 (the focal length scales along)
  int supersampling = 2;     // samples per pixel along each axis (anti-aliasing)
  int threads = 2;           // render threads
  double noise_sigma = 1.5;  // sensor noise, grey levels
  // Throws lmb::Error naming the field for out-of-range values.
  void check() const;
};

// The named presets "tiny", "default" and "paper"; throws lmb::Error for other names.
WorldOptions world_preset(const std::string& name);

// Surfaces of the corridor box.
enum class Surface : int {
  kFloor = 0,
  kCeiling = 1,
  kWallRight = 2,  // y = -width/2, normal +y
  kWallLeft = 3,   // y = +width/2, normal -y
  kEndNear = 4,    // x = 0, normal +x
  kEndFar = 5,     // x = length, normal -x
};
constexpr int kNumSurfaces = 6;

enum class DecalMode : uint8_t { kOpaque, kMultiply, kEmissive };

// A textured rectangle on a surface, in the surface's (a, b) coordinates: a = x on floor, ceiling
// and side walls, a = y on end walls; b = y on floor and ceiling, b = z on walls.
struct Decal {
  Surface surface = Surface::kFloor;
  double a0 = 0, a1 = 0, b0 = 0, b1 = 0;
  int texture = 0;
  DecalMode mode = DecalMode::kOpaque;
};

// An axis-aligned box (pillar, object) with a texture for the faces along x (normal +-x), along y
// (normal +-y) and the top.
struct Box {
  Eigen::Vector3d lo = Eigen::Vector3d::Zero();
  Eigen::Vector3d hi = Eigen::Vector3d::Zero();
  int texture_x = 0;
  int texture_y = 0;
  int texture_top = 0;
};

// Element counts for world.json and tests.
struct WorldSummary {
  int doors = 0, posters = 0, poster_textures = 0, pillars = 0, plates = 0, signs = 0, stains = 0, objects = 0,
      lamps = 0, floor_tiles = 0, ceiling_panels = 0, textures = 0;
};

struct World {
  WorldOptions options;
  double length = 0, width = 0, height = 0;
  std::vector<Texture> textures;
  std::vector<Decal> decals;    // opaque first, then multiply overlays, then emissive lamps
  std::vector<Box> boxes;       // sorted by lo.x
  double max_box_extent_x = 0;  // largest hi.x - lo.x
  // Floor tiles and ceiling panels: square grids from (0, -width/2), texture per cell (row-major
  // over x index then y index).
  double tile_size = 0.5, panel_size = 0.6;
  int tiles_x = 0, tiles_y = 0, panels_x = 0, panels_y = 0;
  std::vector<int> tile_texture, panel_texture;
  // Plain-wall albedo pattern (0..1): base, skirting below skirting_top, a rail band.
  double wall_albedo = 0.78, skirting_albedo = 0.22, skirting_top = 0.1;
  double rail_albedo = 0.5, rail_z0 = 0.92, rail_z1 = 0.98;
  double end_wall_albedo = 0.7;
  // Ceiling lamps (emitter centres just below the ceiling), equally spaced along x.
  std::vector<Eigen::Vector3d> lamps;
  double lamp_spacing = 2.4, lamp_x0 = 1.2;
  // Decal lookup: per surface, bins of bin_size metres along a (from a = 0 on floor, ceiling and
  // side walls, from a = -width/2 on end walls), each listing the decals that overlap it in order.
  double bin_size = 0.5;
  std::array<std::vector<std::vector<int>>, kNumSurfaces> decal_bins;
  // Door rectangles (Surface, a0, a1, b0, b1) in placement order, for tests.
  std::vector<Decal> doors;
  WorldSummary summary;
};

// Builds the world for `options` (checked first). Deterministic: the same options give the same
// world; the layout depends only on the seed and the sizes, never on non_aliased.
World build_world(const WorldOptions& options);

}  // namespace lmb
