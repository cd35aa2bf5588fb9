#include "train/world/texture.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "common/error.h"
#include "common/random.h"

namespace lmb {

Texture::Texture(const cv::Mat& albedo, double width_m, double height_m) : width_m_(width_m), height_m_(height_m) {
  LMB_CHECK(!albedo.empty() && albedo.type() == CV_8UC1, "texture: expected a non-empty 8-bit image");
  LMB_CHECK(width_m > 0.0 && height_m > 0.0,
            "texture: size must be positive, got " << width_m << " x " << height_m << " m");
  texels_per_metre_ = std::max(albedo.cols / width_m, albedo.rows / height_m);
  levels_.push_back(albedo.clone());
  while (levels_.back().cols > 1 || levels_.back().rows > 1) {
    const cv::Mat& prev = levels_.back();
    cv::Mat next;
    cv::resize(prev, next, cv::Size(std::max(1, (prev.cols + 1) / 2), std::max(1, (prev.rows + 1) / 2)), 0, 0,
               cv::INTER_AREA);
    levels_.push_back(next);
  }
}

float Texture::sample_level(int level, double u, double v) const {
  const cv::Mat& m = levels_[level];
  const double x = std::clamp(u, 0.0, 1.0) * m.cols - 0.5;
  const double y = std::clamp(v, 0.0, 1.0) * m.rows - 0.5;
  const int x0 = static_cast<int>(std::floor(x));
  const int y0 = static_cast<int>(std::floor(y));
  const float fx = static_cast<float>(x - x0);
  const float fy = static_cast<float>(y - y0);
  const int xa = std::clamp(x0, 0, m.cols - 1), xb = std::clamp(x0 + 1, 0, m.cols - 1);
  const int ya = std::clamp(y0, 0, m.rows - 1), yb = std::clamp(y0 + 1, 0, m.rows - 1);
  const uint8_t* ra = m.ptr<uint8_t>(ya);
  const uint8_t* rb = m.ptr<uint8_t>(yb);
  const float top = ra[xa] + fx * (ra[xb] - ra[xa]);
  const float bottom = rb[xa] + fx * (rb[xb] - rb[xa]);
  return (top + fy * (bottom - top)) * (1.0f / 255.0f);
}

float Texture::sample(double u, double v, double lod) const {
  const double max_lod = static_cast<double>(levels_.size() - 1);
  lod = std::clamp(lod, 0.0, max_lod);
  const int l0 = static_cast<int>(lod);
  const float f = static_cast<float>(lod - l0);
  const float a = sample_level(l0, u, v);
  if (f <= 0.0f || l0 + 1 >= static_cast<int>(levels_.size())) return a;
  return a + f * (sample_level(l0 + 1, u, v) - a);
}

namespace {

int px(double metres) { return static_cast<int>(std::lround(metres * kTexelsPerMetre)); }

cv::Mat canvas(double width_m, double height_m, int value) {
  return cv::Mat(std::max(1, px(height_m)), std::max(1, px(width_m)), CV_8UC1, cv::Scalar(value));
}

int rand_int(Rng& rng, int lo, int hi) {  // inclusive
  return lo + static_cast<int>(rng.below(static_cast<uint64_t>(hi - lo + 1)));
}

// Adds zero-mean uniform noise of +-amplitude to every texel.
void add_noise(cv::Mat& m, Rng& rng, int amplitude) {
  for (int r = 0; r < m.rows; ++r) {
    uint8_t* row = m.ptr<uint8_t>(r);
    for (int c = 0; c < m.cols; ++c) {
      const int v = row[c] + rand_int(rng, -amplitude, amplitude);
      row[c] = static_cast<uint8_t>(std::clamp(v, 0, 255));
    }
  }
}

// A soft-edged blob of `value` (blended by a Gaussian-blurred disc mask).
void soft_blob(cv::Mat& m, cv::Point centre, cv::Size axes, double angle, int value, double blur_px) {
  cv::Mat mask = cv::Mat::zeros(m.size(), CV_8UC1);
  cv::ellipse(mask, centre, axes, angle, 0, 360, cv::Scalar(255), cv::FILLED, cv::LINE_AA);
  if (blur_px > 0) cv::GaussianBlur(mask, mask, cv::Size(0, 0), blur_px);
  for (int r = 0; r < m.rows; ++r) {
    uint8_t* row = m.ptr<uint8_t>(r);
    const uint8_t* mr = mask.ptr<uint8_t>(r);
    for (int c = 0; c < m.cols; ++c) {
      if (mr[c] == 0) continue;
      const int a = mr[c];
      row[c] = static_cast<uint8_t>((row[c] * (255 - a) + value * a + 127) / 255);
    }
  }
}

std::string random_word(Rng& rng, int min_len, int max_len) {
  static const char* kSyllables[] = {"LA",  "BO",  "RE",  "MI", "TO", "KA", "NE", "SU", "DI", "VO",
                                     "PRO", "LAB", "TEC", "ON", "AR", "EX", "IN", "UM", "ST", "OR"};
  std::string w;
  const int n = rand_int(rng, min_len, max_len);
  while (static_cast<int>(w.size()) < n) w += kSyllables[rng.below(std::size(kSyllables))];
  return w.substr(0, n);
}

// Draws `text` centred in `box`, scaled to fit its width and height.
void draw_text_fit(cv::Mat& m, const std::string& text, cv::Rect box, int font, int thickness, int value) {
  int baseline = 0;
  const cv::Size s = cv::getTextSize(text, font, 1.0, thickness, &baseline);
  const double scale =
      std::min(box.width / static_cast<double>(s.width), box.height / static_cast<double>(s.height + baseline));
  const cv::Size t = cv::getTextSize(text, font, scale, thickness, &baseline);
  const cv::Point org(box.x + (box.width - t.width) / 2, box.y + (box.height + t.height) / 2);
  cv::putText(m, text, org, font, scale, cv::Scalar(value), thickness, cv::LINE_AA);
}

// A bevelled rectangle: light top/left edges, dark bottom/right edges.
void bevel_rect(cv::Mat& m, cv::Rect r, int fill, int light, int dark, int edge) {
  cv::rectangle(m, r, cv::Scalar(fill), cv::FILLED);
  cv::rectangle(m, cv::Rect(r.x, r.y, r.width, edge), cv::Scalar(light), cv::FILLED);
  cv::rectangle(m, cv::Rect(r.x, r.y, edge, r.height), cv::Scalar(light), cv::FILLED);
  cv::rectangle(m, cv::Rect(r.x, r.y + r.height - edge, r.width, edge), cv::Scalar(dark), cv::FILLED);
  cv::rectangle(m, cv::Rect(r.x + r.width - edge, r.y, edge, r.height), cv::Scalar(dark), cv::FILLED);
}

void random_shapes(cv::Mat& m, Rng& rng, int count, int background) {
  for (int i = 0; i < count; ++i) {
    int value = rand_int(rng, 0, 255);
    if (std::abs(value - background) < 70) value = background > 128 ? rand_int(rng, 0, 60) : rand_int(rng, 195, 255);
    const cv::Point c(rand_int(rng, 0, m.cols - 1), rand_int(rng, 0, m.rows - 1));
    const int size = rand_int(rng, m.cols / 14 + 2, m.cols / 4 + 3);
    switch (rng.below(4)) {
      case 0: cv::circle(m, c, size / 2, cv::Scalar(value), cv::FILLED, cv::LINE_AA); break;
      case 1:
        cv::rectangle(m, cv::Rect(c.x, c.y, size, size * rand_int(rng, 1, 3) / 2), cv::Scalar(value), cv::FILLED);
        break;
      case 2: {
        std::vector<cv::Point> tri = {c, c + cv::Point(size, rand_int(rng, -size / 3, size / 3)),
                                      c + cv::Point(rand_int(rng, 0, size), size)};
        cv::fillConvexPoly(m, tri, cv::Scalar(value), cv::LINE_AA);
        break;
      }
      default:
        cv::line(m, c, c + cv::Point(rand_int(rng, -size, size), rand_int(rng, -size, size)), cv::Scalar(value),
                 rand_int(rng, 3, 9), cv::LINE_AA);
        break;
    }
  }
}

}  // namespace

Texture make_door_texture(uint64_t seed, double width_m, double height_m) {
  Rng rng(counter_hash(seed, 0xD004));
  cv::Mat m = canvas(width_m, height_m, 120);
  // Wood grain: vertical streaks from a smoothed random profile.
  std::vector<double> profile(m.cols);
  const double f1 = rng.uniform(20, 60), f2 = rng.uniform(90, 160), p1 = rng.uniform(0, 6.3), p2 = rng.uniform(0, 6.3);
  double walk = 0.0;
  for (int c = 0; c < m.cols; ++c) {
    walk = 0.9 * walk + rng.uniform(-3, 3);
    profile[c] = 10 * std::sin(c / f1 + p1) + 6 * std::sin(c / f2 + p2) + walk;
  }
  const int base = rand_int(rng, 95, 150);
  for (int r = 0; r < m.rows; ++r) {
    uint8_t* row = m.ptr<uint8_t>(r);
    for (int c = 0; c < m.cols; ++c) row[c] = static_cast<uint8_t>(std::clamp(base + profile[c], 0.0, 255.0));
  }
  add_noise(m, rng, 4);
  const int W = m.cols, H = m.rows;
  const int frame = px(0.05);
  // Panels: a lower panel always, the upper one either a panel or a glass window.
  const int margin = px(0.12);
  const int split = H * rand_int(rng, 40, 55) / 100;
  bevel_rect(m, cv::Rect(margin, split + margin / 2, W - 2 * margin, H - split - margin - px(0.25)), base - 15,
             std::min(255, base + 60), std::max(0, base - 70), px(0.015));
  if (rng.below(2) == 0) {
    const cv::Rect glass(margin + px(0.05), margin, W - 2 * margin - px(0.1), split - margin);
    cv::rectangle(m, glass, cv::Scalar(45), cv::FILLED);
    cv::line(m, glass.tl() + cv::Point(glass.width / 5, glass.height), glass.tl() + cv::Point(glass.width * 3 / 5, 0),
             cv::Scalar(150), px(0.03), cv::LINE_AA);
    cv::rectangle(m, glass, cv::Scalar(220), px(0.012));
  } else {
    bevel_rect(m, cv::Rect(margin, margin, W - 2 * margin, split - margin), base - 15, std::min(255, base + 60),
               std::max(0, base - 70), px(0.015));
  }
  // Kick plate with brushed lines.
  const cv::Rect kick(px(0.02), H - px(0.22), W - px(0.04), px(0.2));
  cv::rectangle(m, kick, cv::Scalar(200), cv::FILLED);
  for (int i = 0; i < 12; ++i) {
    const int y = kick.y + rand_int(rng, 2, kick.height - 3);
    cv::line(m, cv::Point(kick.x + rand_int(rng, 0, W / 3), y), cv::Point(kick.x + rand_int(rng, W / 2, W - 10), y),
             cv::Scalar(rand_int(rng, 150, 240)), 1);
  }
  cv::rectangle(m, kick, cv::Scalar(90), 3);
  // Handle: rose, lever and key hole about 1.0 m above the floor.
  const int hx = W - px(0.12), hy = H - px(1.0);
  cv::circle(m, cv::Point(hx, hy), px(0.03), cv::Scalar(215), cv::FILLED, cv::LINE_AA);
  cv::rectangle(m, cv::Rect(hx - px(0.13), hy - px(0.012), px(0.13), px(0.024)), cv::Scalar(30), cv::FILLED);
  cv::circle(m, cv::Point(hx, hy + px(0.09)), px(0.012), cv::Scalar(25), cv::FILLED, cv::LINE_AA);
  // A small sticker and the frame.
  if (rng.below(2) == 0) {
    const cv::Rect sticker(W / 2 - px(0.08), split - px(0.02), px(0.16), px(0.06));
    cv::rectangle(m, sticker, cv::Scalar(235), cv::FILLED);
    draw_text_fit(m, random_word(rng, 4, 6), sticker, cv::FONT_HERSHEY_SIMPLEX, 2, 20);
  }
  cv::rectangle(m, cv::Rect(0, 0, W, H + frame), cv::Scalar(55), frame);
  return Texture(m, width_m, height_m);
}

Texture make_poster_texture(uint64_t seed, double width_m, double height_m) {
  Rng rng(counter_hash(seed, 0xB057));
  const int background = rand_int(rng, 30, 230);
  cv::Mat m = canvas(width_m, height_m, background);
  random_shapes(m, rng, rand_int(rng, 6, 12), background);
  const int text_value = background > 128 ? rand_int(rng, 0, 50) : rand_int(rng, 200, 255);
  const int lines = rand_int(rng, 2, 4);
  for (int i = 0; i < lines; ++i) {
    const cv::Rect box(m.cols / 10, m.rows * (6 + 2 * i) / 12 - m.rows / 24, m.cols * 8 / 10, m.rows / 12);
    const std::string text = random_word(rng, 3, 6) + " " + random_word(rng, 2, 5);
    cv::rectangle(m, box, cv::Scalar(background), cv::FILLED);
    draw_text_fit(m, text, box, rng.below(2) ? cv::FONT_HERSHEY_DUPLEX : cv::FONT_HERSHEY_SIMPLEX, rand_int(rng, 2, 4),
                  text_value);
  }
  // A title band and a frame.
  const cv::Rect title(0, m.rows / 25, m.cols, m.rows / 7);
  cv::rectangle(m, title, cv::Scalar(text_value), cv::FILLED);
  draw_text_fit(m, random_word(rng, 4, 8),
                cv::Rect(title.x + m.cols / 12, title.y + 4, title.width * 5 / 6, title.height - 8),
                cv::FONT_HERSHEY_TRIPLEX, 4, background);
  cv::rectangle(m, cv::Rect(0, 0, m.cols, m.rows), cv::Scalar(20), px(0.015));
  return Texture(m, width_m, height_m);
}

Texture make_floor_tile_texture(uint64_t seed, double size_m) {
  Rng rng(counter_hash(seed, 0xF100));
  const int base = rand_int(rng, 120, 150);
  cv::Mat m = canvas(size_m, size_m, base);
  add_noise(m, rng, 6);
  const int speckles = rand_int(rng, 45, 70);
  for (int i = 0; i < speckles; ++i) {
    const cv::Point c(rand_int(rng, 8, m.cols - 9), rand_int(rng, 8, m.rows - 9));
    const int value = rng.below(2) ? rand_int(rng, 30, 70) : rand_int(rng, 200, 245);
    const cv::Size axes(rand_int(rng, 2, 7), rand_int(rng, 2, 7));
    cv::ellipse(m, c, axes, rand_int(rng, 0, 179), 0, 360, cv::Scalar(value), cv::FILLED, cv::LINE_AA);
  }
  const int grout = px(0.006);
  cv::rectangle(m, cv::Rect(0, 0, m.cols, m.rows), cv::Scalar(60), grout);
  return Texture(m, size_m, size_m);
}

Texture make_ceiling_panel_texture(uint64_t seed, double size_m) {
  Rng rng(counter_hash(seed, 0xCE11));
  cv::Mat m = canvas(size_m, size_m, 205);
  add_noise(m, rng, 5);
  const int fissures = rand_int(rng, 25, 40);
  for (int i = 0; i < fissures; ++i) {
    cv::Point p(rand_int(rng, 10, m.cols - 11), rand_int(rng, 10, m.rows - 11));
    const int value = rand_int(rng, 90, 140);
    for (int k = 0; k < 4; ++k) {
      const cv::Point q = p + cv::Point(rand_int(rng, -9, 9), rand_int(rng, -9, 9));
      cv::line(m, p, q, cv::Scalar(value), rand_int(rng, 2, 3), cv::LINE_AA);
      p = q;
    }
  }
  // T-bar grid with a shadow line.
  const int bar = px(0.018);
  cv::rectangle(m, cv::Rect(0, 0, m.cols, m.rows), cv::Scalar(240), bar);
  cv::rectangle(m, cv::Rect(bar / 2 + 1, bar / 2 + 1, m.cols - bar - 2, m.rows - bar - 2), cv::Scalar(120), 2);
  return Texture(m, size_m, size_m);
}

Texture make_lamp_texture(uint64_t seed, double width_m, double height_m) {
  Rng rng(counter_hash(seed, 0x1A4F));
  cv::Mat m = canvas(width_m, height_m, 255);
  add_noise(m, rng, 3);
  const int bars_x = rand_int(rng, 2, 4), bars_y = rand_int(rng, 5, 9);
  for (int i = 1; i <= bars_x; ++i) {
    const int x = m.cols * i / (bars_x + 1);
    cv::line(m, cv::Point(x, 0), cv::Point(x, m.rows), cv::Scalar(110), px(0.012));
  }
  for (int i = 1; i <= bars_y; ++i) {
    const int y = m.rows * i / (bars_y + 1);
    cv::line(m, cv::Point(0, y), cv::Point(m.cols, y), cv::Scalar(140), px(0.008));
  }
  cv::rectangle(m, cv::Rect(0, 0, m.cols, m.rows), cv::Scalar(150), px(0.03));
  return Texture(m, width_m, height_m);
}

Texture make_pillar_texture(uint64_t seed, double width_m, double height_m) {
  Rng rng(counter_hash(seed, 0x9111));
  cv::Mat m = canvas(width_m, height_m, rand_int(rng, 150, 185));
  add_noise(m, rng, 7);
  // Coarse concrete blotches.
  for (int i = 0; i < 20; ++i) {
    soft_blob(m, cv::Point(rand_int(rng, 0, m.cols), rand_int(rng, 0, m.rows)),
              cv::Size(rand_int(rng, 8, 30), rand_int(rng, 8, 30)), 0, rand_int(rng, 130, 200), 4);
  }
  // Corner guards.
  const int guard = px(0.025);
  cv::rectangle(m, cv::Rect(0, 0, guard, m.rows), cv::Scalar(215), cv::FILLED);
  cv::rectangle(m, cv::Rect(m.cols - guard, 0, guard, m.rows), cv::Scalar(215), cv::FILLED);
  cv::line(m, cv::Point(guard, 0), cv::Point(guard, m.rows), cv::Scalar(70), 2);
  cv::line(m, cv::Point(m.cols - guard, 0), cv::Point(m.cols - guard, m.rows), cv::Scalar(70), 2);
  // A pictogram sign at 1.6-1.9 m and an inspection label at 1.2 m.
  const int sy = m.rows - px(1.9), side = std::min(m.cols - 2 * guard - 8, px(0.22));
  const cv::Rect sign((m.cols - side) / 2, sy, side, side);
  cv::rectangle(m, sign, cv::Scalar(70), cv::FILLED);
  cv::circle(m, sign.tl() + cv::Point(side / 2, side / 3), side / 6, cv::Scalar(240), cv::FILLED, cv::LINE_AA);
  cv::rectangle(m, cv::Rect(sign.x + side / 3, sign.y + side / 2, side / 3, side / 3), cv::Scalar(240), cv::FILLED);
  const cv::Rect label((m.cols - px(0.14)) / 2, m.rows - px(1.25), px(0.14), px(0.08));
  cv::rectangle(m, label, cv::Scalar(235), cv::FILLED);
  draw_text_fit(m, random_word(rng, 3, 5), label, cv::FONT_HERSHEY_SIMPLEX, 2, 30);
  // Skirting.
  cv::rectangle(m, cv::Rect(0, m.rows - px(0.1), m.cols, px(0.1)), cv::Scalar(50), cv::FILLED);
  return Texture(m, width_m, height_m);
}

Texture make_plate_texture(uint64_t seed, const std::string& text, double width_m, double height_m,
                           bool dark_background) {
  Rng rng(counter_hash(seed, 0x91A7));
  const int bg = dark_background ? rand_int(rng, 25, 60) : rand_int(rng, 215, 245);
  const int fg = dark_background ? 240 : 20;
  cv::Mat m = canvas(width_m, height_m, bg);
  const int border = std::max(2, px(0.008));
  cv::rectangle(m, cv::Rect(0, 0, m.cols, m.rows), cv::Scalar(fg), border);
  draw_text_fit(m, text, cv::Rect(border * 3, border * 3, m.cols - 6 * border, m.rows - 6 * border),
                cv::FONT_HERSHEY_SIMPLEX, std::max(2, px(0.006)), fg);
  return Texture(m, width_m, height_m);
}

Texture make_stain_texture(uint64_t seed, double width_m, double height_m) {
  Rng rng(counter_hash(seed, 0x57A1));
  cv::Mat m = canvas(width_m, height_m, 255);
  if (rng.below(3) == 0) {
    // Scuff marks: dark short strokes.
    const int strokes = rand_int(rng, 3, 8);
    for (int i = 0; i < strokes; ++i) {
      const cv::Point a(rand_int(rng, 0, m.cols - 1), rand_int(rng, 0, m.rows - 1));
      const cv::Point b = a + cv::Point(rand_int(rng, -m.cols / 2, m.cols / 2), rand_int(rng, -m.rows / 6, m.rows / 6));
      cv::line(m, a, b, cv::Scalar(rand_int(rng, 60, 140)), rand_int(rng, 2, 6), cv::LINE_AA);
    }
    cv::GaussianBlur(m, m, cv::Size(0, 0), 1.0);
  } else {
    const int blobs = rand_int(rng, 2, 6);
    for (int i = 0; i < blobs; ++i) {
      soft_blob(m, cv::Point(rand_int(rng, m.cols / 4, m.cols * 3 / 4), rand_int(rng, m.rows / 4, m.rows * 3 / 4)),
                cv::Size(rand_int(rng, m.cols / 10, m.cols / 4), rand_int(rng, m.rows / 10, m.rows / 4)),
                rand_int(rng, 0, 179), rand_int(rng, 70, 170), rng.uniform(1.0, 4.0));
    }
  }
  return Texture(m, width_m, height_m);
}

Texture make_object_texture(uint64_t seed, double width_m, double height_m) {
  Rng rng(counter_hash(seed, 0x0B1E));
  const int background = rand_int(rng, 40, 210);
  cv::Mat m = canvas(width_m, height_m, background);
  add_noise(m, rng, 5);
  const int panels = rand_int(rng, 1, 3);
  for (int i = 0; i < panels; ++i) {
    const int h = m.rows / panels;
    bevel_rect(m, cv::Rect(m.cols / 12, i * h + h / 12, m.cols * 10 / 12, h * 10 / 12), background,
               std::min(255, background + 50), std::max(0, background - 60), 4);
  }
  random_shapes(m, rng, rand_int(rng, 2, 5), background);
  const cv::Rect label(m.cols / 4, m.rows / 3, m.cols / 2, std::max(8, m.rows / 8));
  cv::rectangle(m, label, cv::Scalar(240), cv::FILLED);
  draw_text_fit(m, random_word(rng, 3, 7), label, cv::FONT_HERSHEY_SIMPLEX, 2, 15);
  cv::rectangle(m, cv::Rect(0, 0, m.cols, m.rows), cv::Scalar(30), 3);
  return Texture(m, width_m, height_m);
}

}  // namespace lmb
