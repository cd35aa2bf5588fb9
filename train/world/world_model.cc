#include "train/world/world_model.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

#include "common/error.h"
#include "common/random.h"

namespace lmb {

void WorldOptions::check() const {
  LMB_CHECK(preset == "tiny" || preset == "default" || preset == "paper",
            "world: unknown preset '" << preset << "' (expected tiny, default or paper)");
  LMB_CHECK(std::isfinite(length_m) && length_m >= 4.0 && length_m <= 2000.0,
            "world: --length must be in [4, 2000] m, got " << length_m);
  LMB_CHECK(std::isfinite(width_m) && width_m >= 1.6 && width_m <= 6.0,
            "world: corridor width must be in [1.6, 6] m, got " << width_m);
  LMB_CHECK(std::isfinite(height_m) && height_m >= 2.3 && height_m <= 5.0,
            "world: ceiling height must be in [2.3, 5] m, got " << height_m);
  LMB_CHECK(map_frames >= 1 && map_frames <= 1000000, "world: --map-frames must be >= 1, got " << map_frames);
  LMB_CHECK(query_frames >= 1 && query_frames <= 1000000, "world: --query-frames must be >= 1, got " << query_frames);
  LMB_CHECK(map_sessions >= 1 && map_sessions <= kMaxMapSessions,
            "world: --map-sessions must be in [1, " << kMaxMapSessions << "], got " << map_sessions);
  LMB_CHECK(query_sessions >= 1 && query_sessions <= kMaxQuerySessions,
            "world: --query-sessions must be in [1, " << kMaxQuerySessions << "], got " << query_sessions);
  LMB_CHECK(outside_frames >= 0 && outside_frames <= 1000000,
            "world: --outside-frames must be in [0, 1000000], got " << outside_frames);
  LMB_CHECK(region == 0 || region == 1, "world: region must be 0 or 1, got " << region);
  LMB_CHECK(map_frames >= map_sessions,
            "world: --map-frames " << map_frames << " cannot be shared by " << map_sessions << " map sessions");
  LMB_CHECK(poster_designs >= 1 && poster_designs <= 64,
            "world: poster designs must be in [1, 64], got " << poster_designs);
  LMB_CHECK(std::isfinite(pillar_bay_m) && pillar_bay_m >= 1.5 && pillar_bay_m <= 100.0,
            "world: pillar bay must be in [1.5, 100] m, got " << pillar_bay_m);
  LMB_CHECK(
      door_share >= 0.0 && poster_share >= 0.0 && sign_share >= 0.0 && door_share + poster_share + sign_share <= 1.0,
      "world: door, poster and sign shares must be >= 0 with a sum <= 1, got " << door_share << ", " << poster_share
                                                                               << ", " << sign_share);
  LMB_CHECK(std::isfinite(wall_stains_per_m) && wall_stains_per_m >= 0.0 && wall_stains_per_m <= 10.0 &&
                std::isfinite(floor_stains_per_m) && floor_stains_per_m >= 0.0 && floor_stains_per_m <= 10.0,
            "world: stains per metre must be in [0, 10], got " << wall_stains_per_m << " (walls), "
                                                               << floor_stains_per_m << " (floor)");
  LMB_CHECK(std::isfinite(image_scale) && image_scale >= 0.25 && image_scale <= 2.0,
            "world: image scale must be in [0.25, 2], got " << image_scale);
  LMB_CHECK(supersampling >= 1 && supersampling <= 4, "world: supersampling must be in [1, 4], got " << supersampling);
  LMB_CHECK(threads >= 1 && threads <= 64, "world: --threads must be in [1, 64], got " << threads);
  LMB_CHECK(std::isfinite(noise_sigma) && noise_sigma >= 0.0 && noise_sigma <= 50.0,
            "world: noise sigma must be in [0, 50] grey levels, got " << noise_sigma);
}

WorldOptions world_preset(const std::string& name) {
  WorldOptions o;
  o.preset = name;
  if (name == "tiny") {
    o.length_m = 8.0;
    o.map_frames = 30;
    o.query_frames = 10;
  } else if (name == "default") {
    // Strong aliasing at a small size (docs/evaluation.md, "The rendered worlds and their aliasing"): dense
    // half-resolution frames, many repeats of one door, two poster designs and pillars every 3 m, few unique stains and
    // signs. 200 map frames (9 cm apart) give the classifier's top 1,000 landmarks about 5 training observations each;
    // 100 gave 3-4, too few to learn from.
    o.length_m = 18.0;
    o.map_frames = 200;
    o.query_frames = 16;
    o.image_scale = 0.5;
    o.poster_designs = 2;
    o.pillar_bay_m = 3.0;
    o.door_share = 0.5;
    o.poster_share = 0.4;
    o.sign_share = 0.06;
    o.wall_stains_per_m = 0.2;
    o.floor_stains_per_m = 0.15;
  } else if (name == "paper") {
    // Dense frames (1,000 map frames on 37 m of walk, one each way) so that landmarks collect >= 10
    // observations (docs/evaluation.md, "The rendered worlds and their aliasing").
    o.length_m = 40.0;
    o.map_frames = 1000;
    o.query_frames = 150;
  } else {
    LMB_FAIL("world: unknown preset '" << name << "' (expected tiny, default or paper)");
  }
  return o;
}

namespace {

// Texture kinds, the first key of a texture's seed.
enum : uint64_t {
  kDoor = 1,
  kPoster,
  kTile,
  kPanel,
  kLamp,
  kPillarFront,
  kPillarSide,
  kPlate,
  kSign,
  kStain,
  kObject,
  kEndWall
};

class WorldBuilder {
 public:
  // The outside corridor (region 1) draws its layout and unique textures from other keys.
  explicit WorldBuilder(const WorldOptions& options)
      : o_(options),
        layout_(options.region == 0 ? counter_hash(options.seed, 0x1A70)
                                    : counter_hash(options.seed, 0x1A70, static_cast<uint64_t>(options.region))) {
    w_.options = options;
    w_.length = options.length_m;
    w_.width = options.width_m;
    w_.height = options.height_m;
  }

  World build() {
    make_grids();
    make_lamps();
    make_pillars();
    for (Surface s : {Surface::kWallRight, Surface::kWallLeft}) make_wall_items(s);
    make_end_walls();
    make_objects();
    make_stains();
    w_.decals = opaque_;
    w_.decals.insert(w_.decals.end(), multiply_.begin(), multiply_.end());
    w_.decals.insert(w_.decals.end(), emissive_.begin(), emissive_.end());
    std::sort(w_.boxes.begin(), w_.boxes.end(), [](const Box& a, const Box& b) { return a.lo.x() < b.lo.x(); });
    for (const Box& b : w_.boxes) w_.max_box_extent_x = std::max(w_.max_box_extent_x, b.hi.x() - b.lo.x());
    make_bins();
    w_.summary.textures = static_cast<int>(w_.textures.size());
    return std::move(w_);
  }

 private:
  // Seed of a texture: in the aliased world it depends on the design only, in the control world on
  // the instance too. Unique elements pass unique = true.
  uint64_t texture_seed(uint64_t kind, uint64_t design, uint64_t instance, bool unique = false) const {
    if (o_.non_aliased || unique) {
      const uint64_t salt = o_.region == 0 ? 7 : 7 + 1000 * static_cast<uint64_t>(o_.region);
      return counter_hash(o_.seed, kind, 1000000 + instance, salt);
    }
    return counter_hash(o_.seed, kind, design, 3);
  }

  template <typename Make>
  int texture(uint64_t key, Make&& make) {
    const auto it = cache_.find(key);
    if (it != cache_.end()) return it->second;
    w_.textures.push_back(make());
    const int id = static_cast<int>(w_.textures.size()) - 1;
    cache_.emplace(key, id);
    return id;
  }

  void make_grids() {
    w_.tiles_x = static_cast<int>(std::ceil(w_.length / w_.tile_size));
    w_.tiles_y = static_cast<int>(std::ceil(w_.width / w_.tile_size));
    w_.panels_x = static_cast<int>(std::ceil(w_.length / w_.panel_size));
    w_.panels_y = static_cast<int>(std::ceil(w_.width / w_.panel_size));
    for (int i = 0; i < w_.tiles_x * w_.tiles_y; ++i) {
      const uint64_t s = texture_seed(kTile, 0, i);
      w_.tile_texture.push_back(texture(s, [&] { return make_floor_tile_texture(s, w_.tile_size); }));
    }
    for (int i = 0; i < w_.panels_x * w_.panels_y; ++i) {
      const uint64_t s = texture_seed(kPanel, 0, i);
      w_.panel_texture.push_back(texture(s, [&] { return make_ceiling_panel_texture(s, w_.panel_size); }));
    }
    w_.summary.floor_tiles = w_.tiles_x * w_.tiles_y;
    w_.summary.ceiling_panels = w_.panels_x * w_.panels_y;
  }

  void make_lamps() {
    int k = 0;
    for (double x = w_.lamp_x0; x < w_.length - 0.6; x += w_.lamp_spacing, ++k) {
      w_.lamps.emplace_back(x, 0.0, w_.height - 0.02);
      const uint64_t s = texture_seed(kLamp, 0, k);
      const int t = texture(s, [&] { return make_lamp_texture(s, 0.6, 1.2); });
      emissive_.push_back({Surface::kCeiling, x - 0.6, x + 0.6, -0.3, 0.3, t, DecalMode::kEmissive});
    }
    w_.summary.lamps = k;
  }

  void make_pillars() {
    const double bay = o_.pillar_bay_m, half = 0.2, depth = 0.25;
    int k = 0;
    for (double x = bay; x < w_.length - 1.0; x += bay) {
      for (int side = 0; side < 2; ++side, ++k) {
        const uint64_t sf = texture_seed(kPillarFront, 0, k), ss = texture_seed(kPillarSide, 0, k);
        Box b;
        b.texture_y = texture(sf, [&] { return make_pillar_texture(sf, 2 * half, w_.height); });
        b.texture_x = texture(ss, [&] { return make_pillar_texture(ss, depth, w_.height); });
        b.texture_top = b.texture_y;
        const double y0 = side == 0 ? -w_.width / 2 : w_.width / 2 - depth;
        b.lo = Eigen::Vector3d(x - half, y0, 0.0);
        b.hi = Eigen::Vector3d(x + half, y0 + depth, w_.height);
        w_.boxes.push_back(b);
      }
      pillar_x_.push_back(x);
    }
    w_.summary.pillars = k;
  }

  // Doors with room plates, posters and signs along one side wall, bay by bay between pillars.
  void make_wall_items(Surface wall) {
    std::vector<double> edges = {0.3};
    for (double x : pillar_x_) {
      edges.push_back(x - 0.25);
      edges.push_back(x + 0.25);
    }
    edges.push_back(w_.length - 0.3);
    const int side = wall == Surface::kWallLeft ? 1 : 0;
    for (size_t i = 0; i + 1 < edges.size(); i += 2) {
      const double end = edges[i + 1];
      double c = edges[i] + layout_.uniform(0.05, 0.5);
      while (true) {
        const double r = layout_.uniform();
        if (r < o_.door_share) {  // door + room plate
          if (c + 1.3 > end) break;
          const int door_index = w_.summary.doors++;
          const uint64_t s = texture_seed(kDoor, 0, door_index);
          const int t = texture(s, [&] { return make_door_texture(s, 0.95, 2.1); });
          const Decal door{wall, c, c + 0.95, 0.0, 2.1, t, DecalMode::kOpaque};
          opaque_.push_back(door);
          w_.doors.push_back(door);
          char number[32];
          ++room_number_[side];
          std::snprintf(number, sizeof(number), "F%d.%02d", 1 + side, room_number_[side] * 2 - 1 + side);
          const uint64_t ps = texture_seed(kPlate, 0, w_.summary.plates, true);
          const int pt = texture(ps, [&] { return make_plate_texture(ps, number, 0.22, 0.12, false); });
          opaque_.push_back({wall, c + 1.05, c + 1.27, 1.42, 1.54, pt, DecalMode::kOpaque});
          ++w_.summary.plates;
          c += 1.35 + layout_.uniform(0.1, 0.5);
        } else if (r < o_.door_share + o_.poster_share) {  // poster from one of the designs
          if (c + 0.6 > end) break;
          const int design = static_cast<int>(layout_.below(static_cast<uint64_t>(o_.poster_designs)));
          const int poster_index = w_.summary.posters++;
          const uint64_t s = texture_seed(kPoster, design, poster_index);
          const size_t before = w_.textures.size();
          const int t = texture(s, [&] { return make_poster_texture(s, 0.6, 0.85); });
          if (w_.textures.size() > before) ++w_.summary.poster_textures;
          opaque_.push_back({wall, c, c + 0.6, 1.1, 1.95, t, DecalMode::kOpaque});
          c += 0.6 + layout_.uniform(0.15, 0.6);
        } else if (r < o_.door_share + o_.poster_share + o_.sign_share) {  // a small unique sign
          if (c + 0.32 > end) break;
          static const char* kWords[] = {"EXIT",    "LAB",    "FIRE",   "STAIRS", "WC",   "PRINT",
                                         "KITCHEN", "SERVER", "OFFICE", "STORE",  "LIFT", "MEETING"};
          const std::string text =
              std::string(kWords[layout_.below(std::size(kWords))]) + " " + std::to_string(1 + layout_.below(99));
          const bool dark = layout_.below(2) == 0;
          const double z0 = layout_.uniform(1.55, 1.95);
          const uint64_t s = texture_seed(kSign, 0, w_.summary.signs++, true);
          const int t = texture(s, [&] { return make_plate_texture(s, text, 0.32, 0.14, dark); });
          opaque_.push_back({wall, c, c + 0.32, z0, z0 + 0.14, t, DecalMode::kOpaque});
          c += 0.32 + layout_.uniform(0.1, 0.4);
        } else {
          c += layout_.uniform(0.3, 0.8);
        }
      }
    }
  }

  void make_end_walls() {
    for (Surface s : {Surface::kEndNear, Surface::kEndFar}) {
      const uint64_t ts = texture_seed(kEndWall, 0, static_cast<uint64_t>(s), true);
      const int t = texture(ts, [&] { return make_object_texture(ts, 1.2, 1.4); });
      opaque_.push_back({s, -0.6, 0.6, 0.6, 2.0, t, DecalMode::kOpaque});
    }
  }

  bool overlaps_door(Surface wall, double a0, double a1) const {
    for (const Decal& d : w_.doors) {
      if (d.surface == wall && a1 > d.a0 - 0.05 && a0 < d.a1 + 0.05) return true;
    }
    for (double x : pillar_x_) {
      if (a1 > x - 0.25 && a0 < x + 0.25) return true;
    }
    return false;
  }

  // A few unique objects standing against the walls: cabinets, bins and benches.
  void make_objects() {
    const int count = std::max(1, static_cast<int>(w_.length / 6.0));
    for (int i = 0; i < count; ++i) {
      const int kind = static_cast<int>(layout_.below(3));
      const double sx = kind == 0 ? 0.6 : kind == 1 ? 0.4 : 1.2;
      const double sy = kind == 0 ? 0.4 : kind == 1 ? 0.4 : 0.4;
      const double sz = kind == 0 ? 1.1 : kind == 1 ? 0.6 : 0.45;
      const Surface wall = layout_.below(2) ? Surface::kWallLeft : Surface::kWallRight;
      double x0 = -1;
      for (int attempt = 0; attempt < 20; ++attempt) {
        const double x = layout_.uniform(0.4, w_.length - 0.4 - sx);
        if (!overlaps_door(wall, x, x + sx)) {
          x0 = x;
          break;
        }
      }
      if (x0 < 0) continue;
      Box b;
      const uint64_t s = texture_seed(kObject, 0, i, true);
      b.texture_y = texture(s, [&] { return make_object_texture(s, sx, sz); });
      const uint64_t s2 = counter_hash(s, 2);
      b.texture_x = texture(s2, [&] { return make_object_texture(s2, sy, sz); });
      const uint64_t s3 = counter_hash(s, 3);
      b.texture_top = texture(s3, [&] { return make_object_texture(s3, sx, sy); });
      const double y0 = wall == Surface::kWallLeft ? w_.width / 2 - sy : -w_.width / 2;
      b.lo = Eigen::Vector3d(x0, y0, 0.0);
      b.hi = Eigen::Vector3d(x0 + sx, y0 + sy, sz);
      w_.boxes.push_back(b);
      ++w_.summary.objects;
    }
  }

  bool overlaps_opaque(Surface s, double a0, double a1, double b0, double b1) const {
    for (const Decal& d : opaque_) {
      if (d.surface == s && a1 > d.a0 && a0 < d.a1 && b1 > d.b0 && b0 < d.b1) return true;
    }
    return false;
  }

  // Stains and scuffs: multiplicative overlays on plain wall areas and on the floor.
  void make_stains() {
    int k = 0;
    for (Surface wall : {Surface::kWallRight, Surface::kWallLeft}) {
      const int count = static_cast<int>(std::lround(w_.length * o_.wall_stains_per_m));
      for (int i = 0; i < count; ++i) {
        const double sa = layout_.uniform(0.1, 0.4), sb = layout_.uniform(0.06, 0.3);
        const double a0 = layout_.uniform(0.2, w_.length - 0.2 - sa), b0 = layout_.uniform(0.02, 1.6);
        if (overlaps_opaque(wall, a0, a0 + sa, b0, b0 + sb)) continue;
        const uint64_t s = texture_seed(kStain, 0, k++, true);
        const int t = texture(s, [&] { return make_stain_texture(s, sa, sb); });
        multiply_.push_back({wall, a0, a0 + sa, b0, b0 + sb, t, DecalMode::kMultiply});
      }
    }
    const int count = static_cast<int>(std::lround(w_.length * o_.floor_stains_per_m));
    for (int i = 0; i < count; ++i) {
      const double sa = layout_.uniform(0.15, 0.5), sb = layout_.uniform(0.15, 0.5);
      const double a0 = layout_.uniform(0.1, w_.length - 0.1 - sa);
      const double b0 = layout_.uniform(-w_.width / 2 + 0.05, w_.width / 2 - 0.05 - sb);
      const uint64_t s = texture_seed(kStain, 0, k++, true);
      const int t = texture(s, [&] { return make_stain_texture(s, sa, sb); });
      multiply_.push_back({Surface::kFloor, a0, a0 + sa, b0, b0 + sb, t, DecalMode::kMultiply});
    }
    w_.summary.stains = k;
  }

  void make_bins() {
    for (int s = 0; s < kNumSurfaces; ++s) {
      const bool end_wall = s == static_cast<int>(Surface::kEndNear) || s == static_cast<int>(Surface::kEndFar);
      const double extent = end_wall ? w_.width : w_.length;
      w_.decal_bins[s].assign(static_cast<size_t>(std::ceil(extent / w_.bin_size)) + 1, {});
    }
    for (size_t i = 0; i < w_.decals.size(); ++i) {
      const Decal& d = w_.decals[i];
      const int s = static_cast<int>(d.surface);
      const bool end_wall = d.surface == Surface::kEndNear || d.surface == Surface::kEndFar;
      const double origin = end_wall ? -w_.width / 2 : 0.0;
      auto& bins = w_.decal_bins[s];
      const int lo = std::max(0, static_cast<int>(std::floor((d.a0 - origin) / w_.bin_size)));
      const int hi =
          std::min(static_cast<int>(bins.size()) - 1, static_cast<int>(std::floor((d.a1 - origin) / w_.bin_size)));
      for (int b = lo; b <= hi; ++b) bins[b].push_back(static_cast<int>(i));
    }
  }

  const WorldOptions& o_;
  Rng layout_;
  World w_;
  std::map<uint64_t, int> cache_;
  std::vector<double> pillar_x_;
  std::vector<Decal> opaque_, multiply_, emissive_;
  int room_number_[2] = {0, 0};
};

}  // namespace

World build_world(const WorldOptions& options) {
  options.check();
  return WorldBuilder(options).build();
}

}  // namespace lmb
