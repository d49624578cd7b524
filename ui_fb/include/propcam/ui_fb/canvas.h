// The drawing surface of the appliance's screen: an RGB8 image that the UI
// paints into (rectangles, anti-aliased text, scaled camera or render images)
// and that a Display then packs into the framebuffer's pixel format.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string_view>

#include <opencv2/core.hpp>

namespace propcam::ui_fb {

// An 8-bit sRGB colour, as stored in the canvas.
struct Rgb {
  std::uint8_t r = 0;
  std::uint8_t g = 0;
  std::uint8_t b = 0;
  friend bool operator==(const Rgb&, const Rgb&) = default;
};

struct Size {
  int width = 0;
  int height = 0;
  friend bool operator==(const Size&, const Size&) = default;
};

// Pixel rectangle; x,y is the top-left corner. Non-positive width or height means empty.
struct Rect {
  int x = 0;
  int y = 0;
  int width = 0;
  int height = 0;
  bool empty() const { return width <= 0 || height <= 0; }
  int right() const { return x + width; }    // one past the last column
  int bottom() const { return y + height; }  // one past the last row
  friend bool operator==(const Rect&, const Rect&) = default;
};

// The overlap of two rectangles; an empty rectangle (0,0,0,0) when they do not overlap.
Rect intersect(const Rect& a, const Rect& b);

enum class FontWeight { Regular, Bold };

// Where the DejaVu fonts of Debian's fonts-dejavu-core package live.
inline constexpr char kDefaultFontDirectory[] = "/usr/share/fonts/truetype/dejavu";

// The DejaVuSans(-Bold).ttf file in `directory`; throws std::runtime_error naming the
// missing file and the package that provides it.
std::filesystem::path find_font(FontWeight weight,
                                const std::filesystem::path& directory = kDefaultFontDirectory);

// Extent of a line of text relative to the pen position given to draw_text:
// everything it paints lies in columns [x, x + width) and rows
// [y_baseline - ascent, y_baseline + descent).
struct TextExtent {
  int width = 0;
  int ascent = 0;   // pixels above the baseline (at least the font's ascender)
  int descent = 0;  // pixels below the baseline (at least the font's descender)
};

enum class ScaleFilter {
  Bilinear,  // smooth enlargement; aliases when shrinking by more than 2x
  Area,      // averages source pixels: the right choice for shrinking
};

class Canvas {
 public:
  // A black canvas of the given size (both dimensions must be positive).
  Canvas(int width, int height);
  explicit Canvas(Size size) : Canvas(size.width, size.height) {}
  // Draws into an existing CV_8UC3 image in R,G,B byte order, sharing its pixels
  // (a ROI of a larger image works). Throws std::invalid_argument for another type.
  explicit Canvas(cv::Mat rgb);

  // Copies own their pixels, unlike cv::Mat copies, so a copied frame cannot
  // change under the copy's owner.
  Canvas(const Canvas& other);
  Canvas& operator=(const Canvas& other);
  Canvas(Canvas&&) noexcept = default;
  Canvas& operator=(Canvas&&) noexcept = default;

  int width() const { return pixels_.cols; }
  int height() const { return pixels_.rows; }
  Size size() const { return {pixels_.cols, pixels_.rows}; }
  Rect bounds() const { return {0, 0, pixels_.cols, pixels_.rows}; }

  // CV_8UC3, R,G,B byte order.
  const cv::Mat& pixels() const { return pixels_; }
  cv::Mat& pixels() { return pixels_; }

  Rgb pixel(int x, int y) const;  // throws std::out_of_range outside the canvas
  void set_pixel(int x, int y, Rgb colour);  // ignored outside the canvas

  void fill(Rgb colour);
  // Fills the part of `rect` that lies on the canvas.
  void fill_rect(const Rect& rect, Rgb colour);
  // A border `thickness` pixels wide drawn inside `rect`, clipped to the canvas.
  void stroke_rect(const Rect& rect, Rgb colour, int thickness = 1);

  // Draws one line of UTF-8 text with FreeType, anti-aliased by blending `colour`
  // over the canvas with the glyph coverage. `pixel_size` is the em size in pixels.
  // Paints only inside measure_text's box; returns the width of that box.
  // Invalid UTF-8 is drawn as U+FFFD. Throws std::runtime_error if the font is missing.
  int draw_text(int x, int y_baseline, std::string_view utf8, int pixel_size, Rgb colour,
                FontWeight weight = FontWeight::Regular);
  static TextExtent measure_text(std::string_view utf8, int pixel_size,
                                 FontWeight weight = FontWeight::Regular);
  static int text_width(std::string_view utf8, int pixel_size,
                        FontWeight weight = FontWeight::Regular) {
    return measure_text(utf8, pixel_size, weight).width;
  }

  // Scales `image` into `dest` (clipped to the canvas). Accepts CV_8UC3 in R,G,B
  // order or CV_32FC3 linear RGB; float images are filtered in linear light and then
  // encoded with the sRGB transfer function, clamping to [0,1] (NaN becomes 0).
  // With `keep_aspect` the image is fitted inside `dest` and centred, leaving the
  // rest of `dest` untouched. Returns the rectangle the scaled image covers
  // (before clipping). Throws std::invalid_argument for other image types.
  Rect blit_scaled(const cv::Mat& image, const Rect& dest, bool keep_aspect,
                   ScaleFilter filter = ScaleFilter::Bilinear);

 private:
  cv::Mat pixels_;
};

// Encodes linear light in [0,1] as an 8-bit sRGB value with the exact IEC 61966-2-1
// transfer function, rounded to nearest; clamps out-of-range input, NaN gives 0.
std::uint8_t linear_to_srgb8(float linear);

}  // namespace propcam::ui_fb
