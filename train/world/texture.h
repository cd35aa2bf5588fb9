// Textures of the rendered world: grayscale albedo images with a physical size and a mip pyramid,
// and the procedural generators of every element type (doors, posters, tiles, ...). A generator is
// a pure function of its seed: two calls with the same seed give identical textures, which is how
// the aliased world repeats identical elements and the control world makes each one unique.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace lmb {

class Texture {
 public:
  Texture() = default;
  // `albedo`: CV_8UC1 image, 0 = black, 255 = white; it covers width_m x height_m metres (columns
  // along width). Builds the mip pyramid (2x2 box filter down to 1 pixel). Throws lmb::Error on
  // an empty image or non-positive size.
  Texture(const cv::Mat& albedo, double width_m, double height_m);

  // Albedo in [0, 1] at texture coordinates (u, v) in [0, 1] (u along width, v downwards; clamped
  // at the borders), trilinear between the mip levels around `lod` (0 = full resolution).
  float sample(double u, double v, double lod) const;

  // Texels per metre of level 0 (the larger of the two axes).
  double texels_per_metre() const { return texels_per_metre_; }
  int num_levels() const { return static_cast<int>(levels_.size()); }
  const cv::Mat& level(int i) const { return levels_[i]; }
  double width_m() const { return width_m_; }
  double height_m() const { return height_m_; }

 private:
  float sample_level(int level, double u, double v) const;

  std::vector<cv::Mat> levels_;  // CV_8UC1, level 0 = full resolution
  double width_m_ = 0.0;
  double height_m_ = 0.0;
  double texels_per_metre_ = 0.0;
};

// Texel density of generated textures (texels per metre).
constexpr double kTexelsPerMetre = 400.0;

// Element generators. `seed` fixes every random choice; sizes are metres.
Texture make_door_texture(uint64_t seed, double width_m, double height_m);
Texture make_poster_texture(uint64_t seed, double width_m, double height_m);
Texture make_floor_tile_texture(uint64_t seed, double size_m);
Texture make_ceiling_panel_texture(uint64_t seed, double size_m);
Texture make_lamp_texture(uint64_t seed, double width_m, double height_m);
Texture make_pillar_texture(uint64_t seed, double width_m, double height_m);
// A plate with `text` (a room number, a sign's words) in a frame.
Texture make_plate_texture(uint64_t seed, const std::string& text, double width_m, double height_m,
                           bool dark_background);
// A multiplicative overlay (255 = no change): a soft stain or a scuff mark.
Texture make_stain_texture(uint64_t seed, double width_m, double height_m);
// A surface of a unique object (cabinet, bin, bench): panels, labels and scratches.
Texture make_object_texture(uint64_t seed, double width_m, double height_m);

}  // namespace lmb
