#include "propcam/ui_fb/canvas.h"

#include <ft2build.h>
#include FT_FREETYPE_H

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <mutex>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

#include "propcam/capture/image_file.h"

#include <opencv2/imgproc.hpp>

namespace propcam::ui_fb {

Rect intersect(const Rect& a, const Rect& b) {
  const int left = std::max(a.x, b.x);
  const int top = std::max(a.y, b.y);
  const int right = std::min(a.right(), b.right());
  const int bottom = std::min(a.bottom(), b.bottom());
  if (a.empty() || b.empty() || right <= left || bottom <= top) return {};
  return {left, top, right - left, bottom - top};
}

std::filesystem::path find_font(FontWeight weight, const std::filesystem::path& directory) {
  const char* file = weight == FontWeight::Bold ? "DejaVuSans-Bold.ttf" : "DejaVuSans.ttf";
  std::filesystem::path path = directory / file;
  std::error_code ignored;
  if (!std::filesystem::is_regular_file(path, ignored)) {
    throw std::runtime_error("ui_fb: font file " + path.string() +
                             " not found (install the Debian package fonts-dejavu-core)");
  }
  return path;
}

namespace {

constexpr char32_t kReplacementCharacter = 0xFFFD;
constexpr int kMaxPixelSize = 2048;  // guards against absurd glyph bitmaps

// Decodes UTF-8, turning each malformed sequence (bad lead byte, truncation,
// overlong form, surrogate, > U+10FFFF) into U+FFFD and resynchronising after it.
std::u32string decode_utf8(std::string_view text) {
  std::u32string out;
  out.reserve(text.size());
  std::size_t i = 0;
  while (i < text.size()) {
    const auto lead = static_cast<unsigned char>(text[i]);
    int continuation_bytes = 0;
    char32_t code = 0;
    char32_t minimum = 0;
    if (lead < 0x80) {
      out.push_back(lead);
      ++i;
      continue;
    } else if ((lead & 0xE0) == 0xC0) {
      continuation_bytes = 1;
      code = lead & 0x1F;
      minimum = 0x80;
    } else if ((lead & 0xF0) == 0xE0) {
      continuation_bytes = 2;
      code = lead & 0x0F;
      minimum = 0x800;
    } else if ((lead & 0xF8) == 0xF0) {
      continuation_bytes = 3;
      code = lead & 0x07;
      minimum = 0x10000;
    } else {
      out.push_back(kReplacementCharacter);
      ++i;
      continue;
    }
    std::size_t consumed = 1;
    bool valid = true;
    for (int k = 0; k < continuation_bytes; ++k) {
      if (i + consumed >= text.size()) {
        valid = false;
        break;
      }
      const auto next = static_cast<unsigned char>(text[i + consumed]);
      if ((next & 0xC0) != 0x80) {
        valid = false;
        break;
      }
      code = (code << 6) | (next & 0x3F);
      ++consumed;
    }
    if (valid && (code < minimum || code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF))) {
      valid = false;
    }
    out.push_back(valid ? code : kReplacementCharacter);
    i += consumed;
  }
  return out;
}

// A rendered glyph: 8-bit coverage, positioned relative to the pen on the baseline.
struct Glyph {
  int left = 0;  // x of the bitmap's first column relative to the pen
  int top = 0;   // rows of the bitmap above the baseline
  int width = 0;
  int rows = 0;
  long advance_26_6 = 0;  // pen advance in 1/64 pixel
  std::vector<std::uint8_t> coverage;  // width * rows, row-major
};

struct PlacedGlyph {
  const Glyph* glyph;
  int origin_x;  // pen position in whole pixels, relative to the start of the box
};

struct TextLayout {
  std::vector<PlacedGlyph> glyphs;
  TextExtent extent;
};

int round_26_6(long value) { return static_cast<int>((value + 32) >> 6); }
int ceil_26_6(long value) { return static_cast<int>((value + 63) >> 6); }

// FreeType faces are not thread-safe, so one process-wide instance serialises all
// text work behind a mutex and keeps rendered glyphs for reuse between frames.
class FontLibrary {
 public:
  static FontLibrary& instance() {
    static FontLibrary library;
    return library;
  }

  std::mutex& mutex() { return mutex_; }

  // Caller holds mutex(). The returned glyph pointers stay valid until the next layout.
  TextLayout layout(std::string_view utf8, int pixel_size, FontWeight weight) {
    if (pixel_size < 1 || pixel_size > kMaxPixelSize) {
      throw std::invalid_argument("ui_fb: text pixel size " + std::to_string(pixel_size) +
                                  " outside 1.." + std::to_string(kMaxPixelSize));
    }
    FT_Face face = face_for(weight);
    if (FT_Set_Pixel_Sizes(face, 0, static_cast<FT_UInt>(pixel_size)) != 0) {
      throw std::runtime_error("ui_fb: FreeType cannot set pixel size " +
                               std::to_string(pixel_size));
    }
    // Bounded cache: dropping everything occasionally is simpler than LRU and a UI
    // uses few sizes. Safe here because no pointers from an older layout are alive.
    if (glyph_cache_.size() > 4096) glyph_cache_.clear();

    TextLayout result;
    const std::u32string codes = decode_utf8(utf8);
    result.glyphs.reserve(codes.size());
    const bool has_kerning = FT_HAS_KERNING(face);
    long pen = 0;
    FT_UInt previous_index = 0;
    int ink_left = INT_MAX;
    int ink_right = INT_MIN;
    int ink_ascent = 0;
    int ink_descent = 0;
    for (char32_t code : codes) {
      const FT_UInt index = FT_Get_Char_Index(face, code);  // 0 draws the .notdef box
      if (has_kerning && previous_index != 0 && index != 0) {
        FT_Vector delta{};
        if (FT_Get_Kerning(face, previous_index, index, FT_KERNING_DEFAULT, &delta) == 0) {
          pen += delta.x;
        }
      }
      const Glyph& glyph = glyph_for(face, weight, pixel_size, index);
      const int origin = round_26_6(pen);
      if (glyph.width > 0 && glyph.rows > 0) {
        ink_left = std::min(ink_left, origin + glyph.left);
        ink_right = std::max(ink_right, origin + glyph.left + glyph.width);
        ink_ascent = std::max(ink_ascent, glyph.top);
        ink_descent = std::max(ink_descent, glyph.rows - glyph.top);
      }
      result.glyphs.push_back({&glyph, origin});
      pen += glyph.advance_26_6;
      previous_index = index;
    }

    // A glyph may overhang its advance (e.g. 'j' to the left, italics to the right);
    // the box grows to cover it and overhang on the left shifts the text right, so
    // draw_text never paints outside [x, x + width).
    const bool has_ink = ink_left != INT_MAX;
    const int shift = has_ink ? std::max(0, -ink_left) : 0;
    for (PlacedGlyph& placed : result.glyphs) placed.origin_x += shift;
    const int advance = ceil_26_6(pen);
    result.extent.width =
        codes.empty() ? 0 : shift + std::max(advance, has_ink ? ink_right : 0);
    result.extent.ascent = std::max(ceil_26_6(face->size->metrics.ascender), ink_ascent);
    result.extent.descent = std::max(ceil_26_6(-face->size->metrics.descender), ink_descent);
    return result;
  }

 private:
  FontLibrary() {
    if (FT_Init_FreeType(&library_) != 0) {
      throw std::runtime_error("ui_fb: FreeType initialisation failed");
    }
  }
  ~FontLibrary() {
    for (FT_Face face : faces_) {
      if (face != nullptr) FT_Done_Face(face);
    }
    FT_Done_FreeType(library_);
  }

  FT_Face face_for(FontWeight weight) {
    FT_Face& face = faces_[static_cast<std::size_t>(weight)];
    if (face == nullptr) {
      const std::filesystem::path path = find_font(weight);
      const FT_Error error = FT_New_Face(library_, path.c_str(), 0, &face);
      if (error != 0) {
        face = nullptr;
        throw std::runtime_error("ui_fb: FreeType cannot load font " + path.string() +
                                 " (FreeType error " + std::to_string(error) + ")");
      }
    }
    return face;
  }

  const Glyph& glyph_for(FT_Face face, FontWeight weight, int pixel_size, FT_UInt index) {
    const std::uint64_t key = (static_cast<std::uint64_t>(weight) << 48) |
                              (static_cast<std::uint64_t>(pixel_size) << 32) | index;
    if (auto found = glyph_cache_.find(key); found != glyph_cache_.end()) return found->second;

    Glyph glyph;
    // Light hinting keeps glyph shapes faithful while snapping to the pixel grid
    // vertically, which reads best on small panels.
    if (FT_Load_Glyph(face, index, FT_LOAD_RENDER | FT_LOAD_TARGET_LIGHT) == 0) {
      const FT_GlyphSlot slot = face->glyph;
      const FT_Bitmap& bitmap = slot->bitmap;
      glyph.left = slot->bitmap_left;
      glyph.top = slot->bitmap_top;
      glyph.advance_26_6 = slot->advance.x;
      if (bitmap.pixel_mode == FT_PIXEL_MODE_GRAY || bitmap.pixel_mode == FT_PIXEL_MODE_MONO) {
        glyph.width = static_cast<int>(bitmap.width);
        glyph.rows = static_cast<int>(bitmap.rows);
        glyph.coverage.resize(static_cast<std::size_t>(glyph.width) * glyph.rows);
        const int max_grey = bitmap.num_grays > 1 ? bitmap.num_grays - 1 : 255;
        for (int row = 0; row < glyph.rows; ++row) {
          // A negative pitch means the buffer starts with the bottom row.
          const long source_row = bitmap.pitch >= 0 ? row : glyph.rows - 1 - row;
          const unsigned char* source = bitmap.buffer + source_row * std::abs(bitmap.pitch);
          std::uint8_t* target = glyph.coverage.data() + static_cast<std::size_t>(row) * glyph.width;
          for (int col = 0; col < glyph.width; ++col) {
            if (bitmap.pixel_mode == FT_PIXEL_MODE_MONO) {
              target[col] = (source[col >> 3] & (0x80 >> (col & 7))) ? 255 : 0;
            } else {
              target[col] = static_cast<std::uint8_t>(source[col] * 255 / max_grey);
            }
          }
        }
      }
    }
    // A glyph that fails to load keeps zero size and advance: the text still draws.
    return glyph_cache_.emplace(key, std::move(glyph)).first->second;
  }

  std::mutex mutex_;
  FT_Library library_ = nullptr;
  std::array<FT_Face, 2> faces_{};
  std::unordered_map<std::uint64_t, Glyph> glyph_cache_;
};

// Linear values at which the rounded 8-bit sRGB code steps from k-1 to k
// (k = 1..255): the inverse transfer function at the midpoints (k - 0.5) / 255.
// Counting thresholds <= x gives round(255 * srgb(x)) exactly without a pow per pixel.
const std::array<double, 255>& srgb_step_thresholds() {
  static const std::array<double, 255> thresholds = [] {
    std::array<double, 255> result{};
    for (int k = 1; k <= 255; ++k) {
      result[static_cast<std::size_t>(k - 1)] = capture::srgb_to_linear_precise((k - 0.5) / 255.0);
    }
    return result;
  }();
  return thresholds;
}

// The code at the lower edge of each of kSrgbSeedBins equal bins over [0, 1]:
// a lower bound for every value in the bin, from which linear_to_srgb8 walks up
// a step or two instead of binary-searching 255 thresholds (float renders are
// encoded per pixel and channel on every redraw).
constexpr int kSrgbSeedBins = 4096;

const std::array<std::uint8_t, kSrgbSeedBins>& srgb_seed_codes() {
  static const std::array<std::uint8_t, kSrgbSeedBins> seeds = [] {
    const auto& thresholds = srgb_step_thresholds();
    std::array<std::uint8_t, kSrgbSeedBins> result{};
    for (int bin = 0; bin < kSrgbSeedBins; ++bin) {
      const double lower_edge = static_cast<double>(bin) / kSrgbSeedBins;
      result[static_cast<std::size_t>(bin)] = static_cast<std::uint8_t>(
          std::upper_bound(thresholds.begin(), thresholds.end(), lower_edge) - thresholds.begin());
    }
    return result;
  }();
  return seeds;
}

std::uint8_t blend(std::uint8_t background, std::uint8_t foreground, int alpha) {
  return static_cast<std::uint8_t>((foreground * alpha + background * (255 - alpha) + 127) / 255);
}

}  // namespace

std::uint8_t linear_to_srgb8(float linear) {
  if (!(linear > 0.0f)) return 0;  // also catches NaN
  if (linear >= 1.0f) return 255;  // also catches +inf
  const auto& thresholds = srgb_step_thresholds();
  const double value = linear;
  // Counts the thresholds <= value, starting from the bin's lower edge (exact:
  // scaling by a power of two and truncating never lands above value).
  std::size_t code = srgb_seed_codes()[static_cast<std::size_t>(value * kSrgbSeedBins)];
  while (code < thresholds.size() && thresholds[code] <= value) ++code;
  return static_cast<std::uint8_t>(code);
}

Canvas::Canvas(int width, int height) {
  if (width <= 0 || height <= 0) {
    throw std::invalid_argument("ui_fb: canvas size " + std::to_string(width) + "x" +
                                std::to_string(height) + " is not positive");
  }
  pixels_ = cv::Mat(height, width, CV_8UC3, cv::Scalar::all(0));
}

Canvas::Canvas(cv::Mat rgb) : pixels_(std::move(rgb)) {
  if (pixels_.empty() || pixels_.type() != CV_8UC3) {
    throw std::invalid_argument("ui_fb: a Canvas wraps a non-empty CV_8UC3 image");
  }
}

Canvas::Canvas(const Canvas& other) : pixels_(other.pixels_.clone()) {}

Canvas& Canvas::operator=(const Canvas& other) {
  if (this != &other) pixels_ = other.pixels_.clone();
  return *this;
}

Rgb Canvas::pixel(int x, int y) const {
  if (x < 0 || y < 0 || x >= width() || y >= height()) {
    throw std::out_of_range("ui_fb: pixel (" + std::to_string(x) + "," + std::to_string(y) +
                            ") outside the canvas");
  }
  const auto& value = pixels_.at<cv::Vec3b>(y, x);
  return {value[0], value[1], value[2]};
}

void Canvas::set_pixel(int x, int y, Rgb colour) {
  if (x < 0 || y < 0 || x >= width() || y >= height()) return;
  pixels_.at<cv::Vec3b>(y, x) = cv::Vec3b(colour.r, colour.g, colour.b);
}

void Canvas::fill(Rgb colour) { pixels_.setTo(cv::Scalar(colour.r, colour.g, colour.b)); }

void Canvas::fill_rect(const Rect& rect, Rgb colour) {
  const Rect visible = intersect(rect, bounds());
  if (visible.empty()) return;
  pixels_(cv::Rect(visible.x, visible.y, visible.width, visible.height))
      .setTo(cv::Scalar(colour.r, colour.g, colour.b));
}

void Canvas::stroke_rect(const Rect& rect, Rgb colour, int thickness) {
  if (rect.empty() || thickness <= 0) return;
  // Borders thicker than half the rectangle just fill it.
  const int horizontal = std::min(thickness, (rect.height + 1) / 2);
  const int vertical = std::min(thickness, (rect.width + 1) / 2);
  fill_rect({rect.x, rect.y, rect.width, horizontal}, colour);
  fill_rect({rect.x, rect.bottom() - horizontal, rect.width, horizontal}, colour);
  fill_rect({rect.x, rect.y, vertical, rect.height}, colour);
  fill_rect({rect.right() - vertical, rect.y, vertical, rect.height}, colour);
}

TextExtent Canvas::measure_text(std::string_view utf8, int pixel_size, FontWeight weight) {
  FontLibrary& fonts = FontLibrary::instance();
  std::lock_guard lock(fonts.mutex());
  return fonts.layout(utf8, pixel_size, weight).extent;
}

int Canvas::draw_text(int x, int y_baseline, std::string_view utf8, int pixel_size, Rgb colour,
                      FontWeight weight) {
  FontLibrary& fonts = FontLibrary::instance();
  std::lock_guard lock(fonts.mutex());  // glyph bitmaps are shared cache entries
  const TextLayout layout = fonts.layout(utf8, pixel_size, weight);
  const std::uint8_t foreground[3] = {colour.r, colour.g, colour.b};
  for (const PlacedGlyph& placed : layout.glyphs) {
    const Glyph& glyph = *placed.glyph;
    const Rect glyph_box{x + placed.origin_x + glyph.left, y_baseline - glyph.top, glyph.width,
                         glyph.rows};
    const Rect visible = intersect(glyph_box, bounds());
    for (int row = visible.y; row < visible.bottom(); ++row) {
      const std::uint8_t* coverage = glyph.coverage.data() +
                                     static_cast<std::size_t>(row - glyph_box.y) * glyph.width +
                                     (visible.x - glyph_box.x);
      auto* pixel = pixels_.ptr<std::uint8_t>(row) + 3 * visible.x;
      for (int col = 0; col < visible.width; ++col, pixel += 3) {
        const int alpha = coverage[col];
        if (alpha == 0) continue;
        for (int channel = 0; channel < 3; ++channel) {
          pixel[channel] = alpha == 255 ? foreground[channel]
                                        : blend(pixel[channel], foreground[channel], alpha);
        }
      }
    }
  }
  return layout.extent.width;
}

Rect Canvas::blit_scaled(const cv::Mat& image, const Rect& dest, bool keep_aspect,
                         ScaleFilter filter) {
  if (image.empty()) throw std::invalid_argument("ui_fb: blit_scaled of an empty image");
  if (image.type() != CV_8UC3 && image.type() != CV_32FC3) {
    throw std::invalid_argument(
        "ui_fb: blit_scaled accepts CV_8UC3 (RGB) or CV_32FC3 (linear RGB) images");
  }
  if (dest.empty()) return {};

  Rect target = dest;
  if (keep_aspect) {
    const double scale =
        std::min(static_cast<double>(dest.width) / image.cols,
                 static_cast<double>(dest.height) / image.rows);
    target.width = std::clamp(static_cast<int>(std::lround(image.cols * scale)), 1, dest.width);
    target.height = std::clamp(static_cast<int>(std::lround(image.rows * scale)), 1, dest.height);
    target.x = dest.x + (dest.width - target.width) / 2;
    target.y = dest.y + (dest.height - target.height) / 2;
  }
  const Rect visible = intersect(target, bounds());
  if (visible.empty()) return target;

  cv::Mat scaled = image;
  if (image.cols != target.width || image.rows != target.height) {
    const int interpolation = filter == ScaleFilter::Area ? cv::INTER_AREA : cv::INTER_LINEAR;
    cv::resize(image, scaled, cv::Size(target.width, target.height), 0, 0, interpolation);
  }
  const cv::Mat source =
      scaled(cv::Rect(visible.x - target.x, visible.y - target.y, visible.width, visible.height));
  cv::Mat destination = pixels_(cv::Rect(visible.x, visible.y, visible.width, visible.height));
  if (source.type() == CV_8UC3) {
    source.copyTo(destination);
  } else {
    // Float images are scaled in linear light (correct averaging), encoded last.
    for (int row = 0; row < source.rows; ++row) {
      const float* in = source.ptr<float>(row);
      std::uint8_t* out = destination.ptr<std::uint8_t>(row);
      for (int i = 0; i < source.cols * 3; ++i) out[i] = linear_to_srgb8(in[i]);
    }
  }
  return target;
}

}  // namespace propcam::ui_fb
