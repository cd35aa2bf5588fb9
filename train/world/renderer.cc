#include "train/world/renderer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <thread>

#include "common/error.h"
#include "common/random.h"

namespace lmb {

RayTable::RayTable(const Camera& camera, int supersampling) : camera_(camera), ss_(supersampling) {
  camera_.check("world camera");
  LMB_CHECK(supersampling >= 1 && supersampling <= 4, "world: supersampling must be in [1, 4], got " << supersampling);
  const int w = camera_.width, h = camera_.height;
  centres_.resize(static_cast<size_t>(w) * h);
  samples_.resize(static_cast<size_t>(w) * h * ss_ * ss_);
  spacing_.resize(static_cast<size_t>(w) * h);
  double worst = 0.0;
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      const Eigen::Vector2d p(c + 0.5, r + 0.5);
      const Eigen::Vector2d n = camera_.cam_from_img(p);
      worst = std::max(worst, (camera_.img_from_cam(n) - p).norm());
      centres_[static_cast<size_t>(r) * w + c] = n.cast<float>();
      for (int sy = 0; sy < ss_; ++sy) {
        for (int sx = 0; sx < ss_; ++sx) {
          const Eigen::Vector2d q(c + (sx + 0.5) / ss_, r + (sy + 0.5) / ss_);
          samples_[(static_cast<size_t>(r) * w + c) * ss_ * ss_ + sy * ss_ + sx] =
              camera_.cam_from_img(q).cast<float>();
        }
      }
    }
  }
  LMB_CHECK(worst < 1e-3,
            "world camera: undistortion does not round-trip (error " << worst << " px); distortion too strong");
  for (int r = 0; r < h; ++r) {
    for (int c = 0; c < w; ++c) {
      const int c2 = c + 1 < w ? c + 1 : c - 1, r2 = r + 1 < h ? r + 1 : r - 1;
      const Eigen::Vector2f a = centres_[static_cast<size_t>(r) * w + c];
      const float dx = (centres_[static_cast<size_t>(r) * w + c2] - a).norm();
      const float dy = (centres_[static_cast<size_t>(r2) * w + c] - a).norm();
      spacing_[static_cast<size_t>(r) * w + c] = 0.5f * (dx + dy);
    }
  }
}

bool cast_ray(const World& world, const Eigen::Vector3d& o, const Eigen::Vector3d& d, SurfaceHit* hit) {
  // Exit of the corridor box [0, L] x [-W/2, W/2] x [0, H] from inside.
  const double lo[3] = {0.0, -world.width / 2, 0.0};
  const double hi[3] = {world.length, world.width / 2, world.height};
  static constexpr Surface kLoFace[3] = {Surface::kEndNear, Surface::kWallRight, Surface::kFloor};
  static constexpr Surface kHiFace[3] = {Surface::kEndFar, Surface::kWallLeft, Surface::kCeiling};
  double best = std::numeric_limits<double>::infinity();
  int best_axis = -1;
  bool best_hi = false;
  for (int a = 0; a < 3; ++a) {
    if (d[a] > 1e-12) {
      const double t = (hi[a] - o[a]) / d[a];
      if (t < best) {
        best = t;
        best_axis = a;
        best_hi = true;
      }
    } else if (d[a] < -1e-12) {
      const double t = (lo[a] - o[a]) / d[a];
      if (t < best) {
        best = t;
        best_axis = a;
        best_hi = false;
      }
    }
  }
  if (best_axis < 0 || !(best > 0.0)) return false;
  hit->box = -1;
  hit->axis = best_axis;
  hit->surface = best_hi ? kHiFace[best_axis] : kLoFace[best_axis];
  hit->normal = Eigen::Vector3d::Zero();
  hit->normal[best_axis] = best_hi ? -1.0 : 1.0;
  // Boxes whose x-range overlaps the ray's x-span.
  const double x_end = o.x() + best * d.x();
  const double xmin = std::min(o.x(), x_end), xmax = std::max(o.x(), x_end);
  const auto& boxes = world.boxes;
  auto it = std::upper_bound(boxes.begin(), boxes.end(), xmax, [](double x, const Box& b) { return x < b.lo.x(); });
  while (it != boxes.begin()) {
    --it;
    const Box& b = *it;
    if (b.lo.x() < xmin - world.max_box_extent_x) break;
    if (b.hi.x() < xmin) continue;
    double t0 = -std::numeric_limits<double>::infinity(), t1 = best;
    int axis = -1;
    double sign = 0.0;
    bool miss = false;
    for (int a = 0; a < 3 && !miss; ++a) {
      if (std::abs(d[a]) < 1e-12) {
        miss = o[a] < b.lo[a] || o[a] > b.hi[a];
        continue;
      }
      double ta = (b.lo[a] - o[a]) / d[a], tb = (b.hi[a] - o[a]) / d[a];
      if (ta > tb) std::swap(ta, tb);
      if (ta > t0) {
        t0 = ta;
        axis = a;
        sign = d[a] > 0 ? -1.0 : 1.0;
      }
      t1 = std::min(t1, tb);
      miss = t0 > t1;
    }
    if (miss || axis < 0 || !(t0 > 1e-9) || t0 >= best) continue;
    best = t0;
    hit->box = static_cast<int>(it - boxes.begin());
    hit->axis = axis;
    hit->normal = Eigen::Vector3d::Zero();
    hit->normal[axis] = sign;
  }
  hit->t = best;
  hit->point = o + best * d;
  return true;
}

namespace {

float lod_sample(const Texture& tex, double u, double v, double footprint_m) {
  const double texels = tex.texels_per_metre() * footprint_m;
  const double lod = texels > 1.0 ? std::log2(texels) : 0.0;
  return tex.sample(u, v, lod);
}

}  // namespace

float surface_albedo(const World& world, const SurfaceHit& hit, const Eigen::Vector3d& direction, double footprint_m,
                     bool* emissive) {
  *emissive = false;
  const Eigen::Vector3d& p = hit.point;
  // Footprint on the surface: the geometric mean of the two axes of the elongated footprint.
  const double cos_incidence = std::max(0.05, std::abs(direction.dot(hit.normal)) / direction.norm());
  const double fp = footprint_m / std::sqrt(cos_incidence);
  if (hit.box >= 0) {
    const Box& b = world.boxes[hit.box];
    const Eigen::Vector3d e = b.hi - b.lo;
    if (hit.axis == 2) {
      return lod_sample(world.textures[b.texture_top], (p.x() - b.lo.x()) / e.x(), (p.y() - b.lo.y()) / e.y(), fp);
    }
    const double v = (b.hi.z() - p.z()) / e.z();
    if (hit.axis == 0) {
      const double u = (p.y() - b.lo.y()) / e.y();
      return lod_sample(world.textures[b.texture_x], hit.normal.x() > 0 ? u : 1.0 - u, v, fp);
    }
    const double u = (p.x() - b.lo.x()) / e.x();
    return lod_sample(world.textures[b.texture_y], hit.normal.y() > 0 ? 1.0 - u : u, v, fp);
  }
  const Surface s = hit.surface;
  float albedo = 0.0f;
  double a = 0.0, bcoord = 0.0, origin = 0.0;
  bool vertical = true, flip_u = false;
  switch (s) {
    case Surface::kFloor:
    case Surface::kCeiling: {
      a = p.x();
      bcoord = p.y();
      vertical = false;
      const bool floor = s == Surface::kFloor;
      const double cell = floor ? world.tile_size : world.panel_size;
      const int nx = floor ? world.tiles_x : world.panels_x, ny = floor ? world.tiles_y : world.panels_y;
      const double fy = p.y() + world.width / 2;
      const int i = std::clamp(static_cast<int>(std::floor(p.x() / cell)), 0, nx - 1);
      const int j = std::clamp(static_cast<int>(std::floor(fy / cell)), 0, ny - 1);
      const int t = (floor ? world.tile_texture : world.panel_texture)[static_cast<size_t>(i) * ny + j];
      albedo = lod_sample(world.textures[t], p.x() / cell - i, fy / cell - j, fp);
      break;
    }
    case Surface::kWallRight:
    case Surface::kWallLeft:
      a = p.x();
      bcoord = p.z();
      flip_u = s == Surface::kWallRight;
      albedo = static_cast<float>(p.z() < world.skirting_top                          ? world.skirting_albedo
                                  : (p.z() >= world.rail_z0 && p.z() < world.rail_z1) ? world.rail_albedo
                                                                                      : world.wall_albedo);
      break;
    case Surface::kEndNear:
    case Surface::kEndFar:
      a = p.y();
      bcoord = p.z();
      origin = -world.width / 2;
      flip_u = s == Surface::kEndFar;
      albedo = static_cast<float>(p.z() < world.skirting_top ? world.skirting_albedo : world.end_wall_albedo);
      break;
  }
  const auto& bins = world.decal_bins[static_cast<int>(s)];
  const int bin = static_cast<int>(std::floor((a - origin) / world.bin_size));
  if (bin < 0 || bin >= static_cast<int>(bins.size())) return albedo;
  for (int di : bins[bin]) {
    const Decal& d = world.decals[di];
    if (a < d.a0 || a >= d.a1 || bcoord < d.b0 || bcoord >= d.b1) continue;
    double u = (a - d.a0) / (d.a1 - d.a0);
    if (flip_u) u = 1.0 - u;
    const double v = vertical ? (d.b1 - bcoord) / (d.b1 - d.b0) : (bcoord - d.b0) / (d.b1 - d.b0);
    const float value = lod_sample(world.textures[d.texture], u, v, fp);
    switch (d.mode) {
      case DecalMode::kOpaque: albedo = value; break;
      case DecalMode::kMultiply: albedo *= value; break;
      case DecalMode::kEmissive:
        albedo = value;
        *emissive = true;
        break;
    }
  }
  return albedo;
}

namespace {

double irradiance(const World& world, const Lighting& lighting, const Eigen::Vector3d& p, const Eigen::Vector3d& n) {
  constexpr double kCutoff = 6.0;
  double e = lighting.ambient;
  const int k0 = std::max(0, static_cast<int>(std::ceil((p.x() - kCutoff - world.lamp_x0) / world.lamp_spacing)));
  const int k1 = std::min(static_cast<int>(world.lamps.size()) - 1,
                          static_cast<int>(std::floor((p.x() + kCutoff - world.lamp_x0) / world.lamp_spacing)));
  const double inv_range2 = 1.0 / (lighting.lamp_range_m * lighting.lamp_range_m);
  for (int k = k0; k <= k1; ++k) {
    const double scale = lighting.lamp_scale.empty() ? 1.0 : lighting.lamp_scale[k];
    if (scale <= 0.0) continue;
    const Eigen::Vector3d l = world.lamps[k] - p;
    const double r2 = l.squaredNorm();
    const double window = std::max(0.0, 1.0 - r2 / (kCutoff * kCutoff));
    if (window <= 0.0) continue;
    const double inv_r = 1.0 / std::sqrt(r2);
    const double cos_surface = std::max(0.0, n.dot(l) * inv_r);
    const double cos_lamp = std::max(0.0, -l.z() * inv_r);
    e += scale * lighting.lamp_power * cos_surface * cos_lamp * window * window / (1.0 + r2 * inv_range2);
  }
  return e;
}

double gaussian_from_bits(uint64_t bits) {
  const double u1 = (static_cast<double>(bits >> 32) + 0.5) * 0x1.0p-32;
  const double u2 = static_cast<double>(bits & 0xFFFFFFFFull) * 0x1.0p-32;
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

void render_rows(const World& world, const RayTable& rays, const Rigid3d& cam_from_world, const Lighting& lighting,
                 uint64_t frame_key, int first_row, int row_step, RenderedFrame* out) {
  const Camera& cam = rays.camera();
  const int ss2 = rays.supersampling() * rays.supersampling();
  const Eigen::Matrix3d world_from_cam = cam_from_world.rotation.conjugate().toRotationMatrix();
  const Eigen::Vector3d origin = cam_from_world.center();
  for (int r = first_row; r < cam.height; r += row_step) {
    uint8_t* img_row = out->image.ptr<uint8_t>(r);
    uint16_t* depth_row = out->depth_mm.ptr<uint16_t>(r);
    for (int c = 0; c < cam.width; ++c) {
      // The pixel centre's ray gives the depth and the irradiance that sub-samples on the same face
      // reuse (lighting varies slowly across a pixel).
      const Eigen::Vector2f nc = rays.centre(c, r);
      SurfaceHit centre;
      const bool centre_ok = cast_ray(world, origin, world_from_cam * Eigen::Vector3d(nc.x(), nc.y(), 1.0), &centre);
      const uint16_t mm =
          centre_ok ? static_cast<uint16_t>(std::clamp(std::lround(centre.t * 1000.0), 0l, 65535l)) : uint16_t{0};
      double centre_irradiance = -1.0;
      const double footprint_scale = rays.spacing(c, r) / rays.supersampling();
      double radiance = 0.0;
      for (int s = 0; s < ss2; ++s) {
        const Eigen::Vector2f n = rays.sample(c, r, s);
        const Eigen::Vector3d d = world_from_cam * Eigen::Vector3d(n.x(), n.y(), 1.0);
        SurfaceHit hit;
        if (!cast_ray(world, origin, d, &hit)) continue;
        bool emissive = false;
        const float albedo = surface_albedo(world, hit, d, hit.t * footprint_scale, &emissive);
        if (lighting.flat) {
          radiance += albedo;
        } else if (emissive) {
          const int k = static_cast<int>(std::lround((hit.point.x() - world.lamp_x0) / world.lamp_spacing));
          const double scale = lighting.lamp_scale.empty() || k < 0 || k >= static_cast<int>(lighting.lamp_scale.size())
                                   ? 1.0
                                   : lighting.lamp_scale[k];
          radiance += albedo * (lighting.ambient + lighting.emissive * scale);
        } else if (centre_ok && hit.box == centre.box && hit.normal == centre.normal) {
          if (centre_irradiance < 0.0) centre_irradiance = irradiance(world, lighting, centre.point, centre.normal);
          radiance += albedo * centre_irradiance;
        } else {
          radiance += albedo * irradiance(world, lighting, hit.point, hit.normal);
        }
      }
      radiance /= ss2;
      double grey;
      if (lighting.flat) {
        grey = 255.0 * radiance;
      } else {
        grey = 255.0 * lighting.gain * std::pow(std::max(0.0, radiance), lighting.exponent);
        if (lighting.noise_sigma > 0.0) {
          const uint64_t bits = counter_hash(lighting.noise_seed, frame_key, static_cast<uint64_t>(r) * cam.width + c);
          grey += lighting.noise_sigma * gaussian_from_bits(bits);
        }
      }
      img_row[c] = static_cast<uint8_t>(std::clamp(std::lround(grey), 0l, 255l));
      depth_row[c] = mm;
    }
  }
}

}  // namespace

RenderedFrame render_frame(const World& world, const RayTable& rays, const Rigid3d& cam_from_world,
                           const Lighting& lighting, uint64_t frame_key, int threads) {
  LMB_CHECK(threads >= 1, "world: render threads must be >= 1");
  LMB_CHECK(
      lighting.lamp_scale.empty() || lighting.lamp_scale.size() == world.lamps.size(),
      "world: lighting has " << lighting.lamp_scale.size() << " lamp scales for " << world.lamps.size() << " lamps");
  const Camera& cam = rays.camera();
  RenderedFrame out;
  out.image.create(cam.height, cam.width, CV_8UC1);
  out.depth_mm.create(cam.height, cam.width, CV_16UC1);
  if (threads == 1) {
    render_rows(world, rays, cam_from_world, lighting, frame_key, 0, 1, &out);
    return out;
  }
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) {
    pool.emplace_back(render_rows, std::cref(world), std::cref(rays), std::cref(cam_from_world), std::cref(lighting),
                      frame_key, t, threads, &out);
  }
  for (auto& th : pool) th.join();
  return out;
}

}  // namespace lmb
