#include "propcam/render/photo_imaging.h"

#include <opencv2/imgproc.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <mutex>
#include <numbers>
#include <stdexcept>

#include "luminance.h"
#include "propcam/capture/image_file.h"
#include "propcam/render/depth_mesh.h"

namespace propcam::render {
namespace {

using Clock = std::chrono::steady_clock;

// --- noise -----------------------------------------------------------------

// Immerkaer's operator: the difference of two Laplacians, blind to planes
// and linear shading; on white noise of sigma its response has sigma * 6.
constexpr float kImmerkaerGain = 6.0f;
constexpr int kNoiseBlockPx = 8;
// The lower envelope: this quantile of the blocks' sigmas in a bin, divided
// by what the same quantile gives on pure white noise (measured on 4000
// blocks of it: tests/render/photo_imaging_test.cpp checks the ratio).
constexpr double kEnvelopeQuantile = 0.1;
constexpr double kEnvelopeBias = 0.795;
constexpr int kMinBlocksPerBin = 8;
// Blocks touching clipped values have lost their noise.
constexpr float kClipMargin = 1.5f / 255.0f;
// An 8-bit file's own rounding noise (uniform over one level).
constexpr float kQuantisationVariance = (1.0f / 255.0f) * (1.0f / 255.0f) / 12.0f;
// Robust sigma from the median absolute value of a Gaussian.
constexpr double kMadToSigma = 1.4826;

cv::Mat immerkaer_response(const cv::Mat& image) {
  static const cv::Mat kernel = (cv::Mat_<float>(3, 3) << 1, -2, 1, -2, 4, -2, 1, -2, 1);
  cv::Mat r;
  cv::filter2D(image, r, CV_32F, kernel, {-1, -1}, 0, cv::BORDER_REFLECT);
  return r;
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

// A standard normal number that depends only on (seed, x, y, channel).
uint64_t mix(uint64_t z) {
  z += 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

float hashed_gaussian(uint64_t seed, int x, int y, int channel) {
  const uint64_t h = mix(seed ^ mix((static_cast<uint64_t>(static_cast<uint32_t>(y)) << 32) ^
                                    (static_cast<uint64_t>(static_cast<uint32_t>(x)) << 2) ^ static_cast<uint64_t>(channel)));
  const double u1 = (static_cast<double>(h >> 40) + 0.5) / static_cast<double>(1ULL << 24);
  const double u2 = static_cast<double>((h >> 16) & 0xFFFFFF) / static_cast<double>(1ULL << 24);
  return static_cast<float>(std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2));
}

// --- blur ------------------------------------------------------------------

constexpr double kReblurSigmaPx = 1.0;
// An edge counts when the luminance along its gradient is monotone this far
// to each side (no second edge within the re-blur's reach) ...
constexpr int kProfileHalfPx = 4;
constexpr double kMonotoneTolerance = 0.03;  // of the step's height
// ... and its step is at least this share of the brighter side.
constexpr double kMinEdgeContrast = 0.2;
// A photo's edges are its point spread or wider (soft shadows, shading,
// defocus): the lower quartile of the edges' blurs reads the camera's.
constexpr double kEdgeQuantile = 0.25;
constexpr double kMaxBlurSigmaPx = 8.0, kBlurTableStepPx = 0.05;
constexpr int kBlurTablePhases = 8;
// Guards the table's divisions (its differences are of order 0.01-1).
constexpr double kTinyDifference = 1e-12;

int gaussian_ksize(double sigma) { return 2 * static_cast<int>(std::ceil(3.0 * sigma)) + 1; }

double standard_normal_cdf(double x) { return 0.5 * std::erfc(-x / std::numbers::sqrt2); }

// A unit step at `phase` seen through a Gaussian of `sigma` and integrated
// over the pixel centred at x.
double blurred_step_pixel(double x, double phase, double sigma) {
  const double a = x - 0.5 - phase, b = x + 0.5 - phase;
  if (sigma <= 0) return std::clamp(b, 0.0, 1.0);  // the pixel's share above the step
  const auto antiderivative = [sigma](double u) {
    return u * standard_normal_cdf(u / sigma) + sigma * std::exp(-0.5 * u * u / (sigma * sigma)) / std::sqrt(2 * std::numbers::pi);
  };
  return antiderivative(b) - antiderivative(a);
}

// The gradient ratio (original over re-blurred, at the original's steepest
// pixel) an isolated step of blur sigma gives through the same discrete
// operators, averaged over the step's sub-pixel phase; decreasing in sigma.
struct ReblurTable {
  double reblur_sigma = 0;
  std::vector<double> ratio;  // at sigma = i * kBlurTableStepPx

  explicit ReblurTable(double sigma0) : reblur_sigma(sigma0) {
    const int ksize = gaussian_ksize(sigma0), half = ksize / 2;
    const cv::Mat kernel = cv::getGaussianKernel(ksize, sigma0, CV_64F);
    const int entries = static_cast<int>(std::lround(kMaxBlurSigmaPx / kBlurTableStepPx)) + 1;
    // The step sits within half a pixel of pixel 0, so its steepest pixel is
    // within one of it: only the pixels the re-blur there reads are made.
    constexpr int kSearchPx = 2;
    const int reach = kSearchPx + 1 + half;
    std::vector<double> v(2 * reach + 1);
    for (int entry = 0; entry < entries; ++entry) {
      const double sigma = entry * kBlurTableStepPx;
      double sum = 0;
      for (int p = 0; p < kBlurTablePhases; ++p) {
        const double phase = (p + 0.5) / kBlurTablePhases - 0.5;
        for (int i = -reach; i <= reach; ++i) v[i + reach] = blurred_step_pixel(i, phase, sigma);
        const auto at = [&](int i) { return v[i + reach]; };
        int best = -kSearchPx;
        for (int i = -kSearchPx; i <= kSearchPx; ++i)
          if (at(i + 1) - at(i - 1) > at(best + 1) - at(best - 1)) best = i;
        const auto reblurred = [&](int i) {
          double w = 0;
          for (int k = 0; k < ksize; ++k) w += kernel.at<double>(k) * at(i + k - half);
          return w;
        };
        sum += (at(best + 1) - at(best - 1)) / std::max(kTinyDifference, reblurred(best + 1) - reblurred(best - 1));
      }
      ratio.push_back(sum / kBlurTablePhases);
    }
  }

  double sigma_for(double r) const {
    if (r >= ratio.front()) return 0.0;
    for (size_t i = 1; i < ratio.size(); ++i)
      if (r >= ratio[i]) {
        const double t = (ratio[i - 1] - r) / std::max(kTinyDifference, ratio[i - 1] - ratio[i]);
        return (static_cast<double>(i - 1) + t) * kBlurTableStepPx;
      }
    return kMaxBlurSigmaPx;
  }
};

const ReblurTable& reblur_table(double sigma0) {
  static std::mutex mutex;
  static std::vector<std::unique_ptr<ReblurTable>> tables;
  std::lock_guard lock(mutex);
  for (const auto& t : tables)
    if (t->reblur_sigma == sigma0) return *t;
  tables.push_back(std::make_unique<ReblurTable>(sigma0));
  return *tables.back();
}

// The sRGB curve by a table with linear interpolation: the estimate encodes
// every value of a frame, and a pow per value was a third of its time. The
// interpolation's error is below 2e-6 (under 0.001 of an 8-bit level).
class DisplayEncoder {
 public:
  DisplayEncoder() : table_(kEntries + 1) {
    for (int i = 0; i <= kEntries; ++i) table_[i] = capture::linear_to_srgb(static_cast<float>(i) / kEntries);
  }
  // `linear` already within [0, 1].
  float operator()(float linear) const {
    const float t = linear * kEntries;
    const int i = std::min(static_cast<int>(t), kEntries - 1);
    const float f = t - static_cast<float>(i);
    return table_[i] + f * (table_[i + 1] - table_[i]);
  }

 private:
  static constexpr int kEntries = 16384;
  std::vector<float> table_;
};

const DisplayEncoder& display_encoder() {
  static const DisplayEncoder encoder;
  return encoder;
}

float sanitised(float v) { return std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f; }

// The luminance through the sRGB curve in 8 bits, where edges are found.
cv::Mat encoded_luminance_of(const cv::Mat& luminance) {
  const DisplayEncoder& encode = display_encoder();
  cv::Mat encoded(luminance.size(), CV_8U);
  for (int r = 0; r < luminance.rows; ++r) {
    const float* y = luminance.ptr<float>(r);
    uint8_t* e = encoded.ptr<uint8_t>(r);
    for (int c = 0; c < luminance.cols; ++c) e[c] = cv::saturate_cast<uint8_t>(255.0f * encode(std::min(1.0f, y[c])));
  }
  return encoded;
}

// What both estimates read of a linear photo, made in one pass (each
// full-frame temporary costs its page faults): non-finite values as black,
// the rest within [0, 1].
struct PhotoPlanes {
  cv::Mat display;            // CV_32FC3, the sRGB curve's values
  cv::Mat luminance;          // CV_32F, linear
  cv::Mat encoded_luminance;  // CV_8U, encoded_luminance_of(luminance)
};

PhotoPlanes photo_planes(const cv::Mat& linear) {
  const DisplayEncoder& encode = display_encoder();
  PhotoPlanes planes{cv::Mat(linear.size(), CV_32FC3), cv::Mat(linear.size(), CV_32F), {}};
  for (int r = 0; r < linear.rows; ++r) {
    const auto* in = linear.ptr<cv::Vec3f>(r);
    auto* d = planes.display.ptr<cv::Vec3f>(r);
    float* y = planes.luminance.ptr<float>(r);
    for (int c = 0; c < linear.cols; ++c) {
      const cv::Vec3f v{sanitised(in[c][0]), sanitised(in[c][1]), sanitised(in[c][2])};
      d[c] = {encode(v[0]), encode(v[1]), encode(v[2])};
      y[c] = std::min(1.0f, detail::luminance(v));
    }
  }
  planes.encoded_luminance = encoded_luminance_of(planes.luminance);
  return planes;
}

// The linear luminance of an image as it is (a render's, above 1 too),
// negative or non-finite values as 0.
cv::Mat luminance_as_given(const cv::Mat& linear) {
  cv::Mat y(linear.size(), CV_32F);
  for (int r = 0; r < linear.rows; ++r) {
    float* out = y.ptr<float>(r);
    for (int c = 0; c < linear.cols; ++c) {
      const float lum =
          linear.type() == CV_32F ? linear.ptr<float>(r)[c] : detail::luminance(linear.ptr<cv::Vec3f>(r)[c]);
      out[c] = std::isfinite(lum) ? std::max(0.0f, lum) : 0.0f;
    }
  }
  return y;
}

float bilinear(const cv::Mat& image, float x, float y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const float fx = x - x0, fy = y - y0;
  const auto at = [&](int xx, int yy) {
    return image.at<float>(std::clamp(yy, 0, image.rows - 1), std::clamp(xx, 0, image.cols - 1));
  };
  return (1 - fy) * ((1 - fx) * at(x0, y0) + fx * at(x0 + 1, y0)) + fy * ((1 - fx) * at(x0, y0 + 1) + fx * at(x0 + 1, y0 + 1));
}

// OpenCV's 3x3 Sobel gradient at one pixel at least one pixel inside.
cv::Vec2f sobel_at(const cv::Mat& image, int r, int c) {
  const float* up = image.ptr<float>(r - 1);
  const float* mid = image.ptr<float>(r);
  const float* down = image.ptr<float>(r + 1);
  return {(up[c + 1] + 2 * mid[c + 1] + down[c + 1]) - (up[c - 1] + 2 * mid[c - 1] + down[c - 1]),
          (down[c - 1] + 2 * down[c] + down[c + 1]) - (up[c - 1] + 2 * up[c] + up[c + 1])};
}

// The edge pixel nearest to the line through (r, c) along the edge, `t`
// pixels on along it, and its gradient across the edge (0 when none is
// within a pixel of the line): one per row of a steep edge, per column of a
// flat one, so the sum along an edge counts each of its pixels once.
struct AlongEdge {
  int r = 0, c = 0;
  float across = 0;
};

AlongEdge edge_pixel_along(const cv::Mat& y, const cv::Mat& edges, int r, int c, float nx, float ny, int t,
                           int border) {
  const bool steep = std::abs(nx) >= std::abs(ny);  // the edge runs more down than across
  const float shift = steep ? -static_cast<float>(t) * ny / nx : -static_cast<float>(t) * nx / ny;
  AlongEdge best;
  for (int k = -1; k <= 1; ++k) {
    const int offset = static_cast<int>(std::lround(shift)) + k;
    const int r2 = steep ? r + t : r + offset, c2 = steep ? c + offset : c + t;
    if (r2 < border || r2 >= y.rows - border || c2 < border || c2 >= y.cols - border || !edges.at<uint8_t>(r2, c2))
      continue;
    const cv::Vec2f g = sobel_at(y, r2, c2);
    const float across = g[0] * nx + g[1] * ny;
    if (across > best.across) best = {r2, c2, across};
  }
  return best;
}

// The blur at each isolated edge pixel, re-blurred with sigma0. The
// gradients are taken at the edge pixels only; with `along_px` > 0 each
// pixel's two gradients are summed over the edge's pixels up to that far
// along it (which averages noise away and leaves the profile across the
// edge as it is).
std::vector<double> edge_blurs(const cv::Mat& y, const cv::Mat& edges, const cv::Mat& mask, double sigma0,
                               int along_px = 0, std::vector<cv::Point>* at = nullptr) {
  const ReblurTable& table = reblur_table(sigma0);
  const int ksize = gaussian_ksize(sigma0);
  cv::Mat reblurred;
  cv::GaussianBlur(y, reblurred, {ksize, ksize}, sigma0, sigma0, cv::BORDER_REFLECT);
  const int border = kProfileHalfPx + ksize / 2 + 2;
  std::vector<double> sigmas;
  for (int r = border; r < y.rows - border; ++r)
    for (int c = border; c < y.cols - border; ++c) {
      if (!edges.at<uint8_t>(r, c) || (!mask.empty() && !mask.at<uint8_t>(r, c))) continue;
      const cv::Vec2f grad = sobel_at(y, r, c);
      const float g = std::hypot(grad[0], grad[1]);
      if (!(g > 0)) continue;
      const float nx = grad[0] / g, ny = grad[1] / g;
      float profile[2 * kProfileHalfPx + 1];
      for (int k = -kProfileHalfPx; k <= kProfileHalfPx; ++k)
        profile[k + kProfileHalfPx] = bilinear(y, c + k * nx, r + k * ny);
      const float low = profile[0], high = profile[2 * kProfileHalfPx];
      const float step = high - low;  // positive: the gradient points up the step
      if (!(step > kMinEdgeContrast * std::max(high, 1e-6f))) continue;
      bool monotone = true;
      for (int k = 0; k < 2 * kProfileHalfPx && monotone; ++k)
        monotone = profile[k + 1] - profile[k] >= -kMonotoneTolerance * step;
      if (!monotone) continue;
      const cv::Vec2f grad1 = sobel_at(reblurred, r, c);
      const float g1 = std::hypot(grad1[0], grad1[1]);
      if (!(g1 > 0)) continue;
      float g_sum = g, g1_sum = g1;
      for (int t = -along_px; t <= along_px; ++t) {
        const AlongEdge p = t == 0 ? AlongEdge{} : edge_pixel_along(y, edges, r, c, nx, ny, t, border);
        if (!(p.across > 0)) continue;
        const cv::Vec2f q = sobel_at(reblurred, p.r, p.c);
        g_sum += p.across;
        g1_sum += q[0] * nx + q[1] * ny;
      }
      if (!(g1_sum > 0)) continue;
      sigmas.push_back(table.sigma_for(g_sum / g1_sum));
      if (at) at->push_back({c, r});
    }
  return sigmas;
}

// Display values (the sRGB curve) of linear sRGB clamped to [0, 1], and back.
cv::Mat to_display(const cv::Mat& srgb_linear) {
  const DisplayEncoder& encode = display_encoder();
  cv::Mat display(srgb_linear.size(), CV_32FC3);
  for (int r = 0; r < display.rows; ++r) {
    const auto* in = srgb_linear.ptr<cv::Vec3f>(r);
    auto* o = display.ptr<cv::Vec3f>(r);
    for (int c = 0; c < display.cols; ++c)
      for (int k = 0; k < 3; ++k) o[c][k] = encode(sanitised(in[c][k]));
  }
  return display;
}

cv::Mat to_srgb_linear(const cv::Mat& display) {
  cv::Mat linear(display.size(), CV_32FC3);
  for (int r = 0; r < linear.rows; ++r) {
    const auto* in = display.ptr<cv::Vec3f>(r);
    auto* o = linear.ptr<cv::Vec3f>(r);
    for (int c = 0; c < linear.cols; ++c)
      for (int k = 0; k < 3; ++k) o[c][k] = capture::srgb_to_linear(in[c][k]);
  }
  return linear;
}

// The bounding box of the pixels of `size` where counts(row, column) holds
// (empty when none), without a full-frame mask.
template <class Counts>
cv::Rect bounds_where(cv::Size size, Counts counts) {
  int x0 = size.width, y0 = size.height, x1 = -1, y1 = -1;
  for (int r = 0; r < size.height; ++r)
    for (int x = 0; x < size.width; ++x) {
      if (!counts(r, x)) continue;
      x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, r), y1 = std::max(y1, r);
    }
  return x1 < 0 ? cv::Rect() : cv::Rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1);
}

// Where `composite` differs from `photo` or `coverage` is non-zero.
cv::Rect changed_bounds(const cv::Mat& photo, const cv::Mat& composite, const cv::Mat& coverage) {
  return bounds_where(coverage.size(), [&](int r, int x) {
    return coverage.ptr<float>(r)[x] != 0 || composite.ptr<cv::Vec3f>(r)[x] != photo.ptr<cv::Vec3f>(r)[x];
  });
}

cv::Rect covered_bounds(const cv::Mat& coverage) {
  return bounds_where(coverage.size(), [&](int r, int x) { return coverage.ptr<float>(r)[x] > 0; });
}

}  // namespace

float NoiseLevelFunction::at(int channel, float display_value) const {
  const float t = std::clamp(display_value * kNoiseBins - 0.5f, 0.0f, static_cast<float>(kNoiseBins - 1));
  const int i = std::min(static_cast<int>(t), kNoiseBins - 2);
  const float f = t - static_cast<float>(i);
  return (1 - f) * sigma[i][channel] + f * sigma[i + 1][channel];
}

double NoiseLevelFunction::median_8bit() const {
  std::vector<double> all;
  for (const auto& bin : sigma)
    for (float s : bin) all.push_back(s);
  std::nth_element(all.begin(), all.begin() + static_cast<long>(all.size() / 2), all.end());
  return 255.0 * all[all.size() / 2];
}

NoiseLevelFunction estimate_noise_level(const cv::Mat& display, const cv::Mat& mask, int* blocks_used) {
  if (display.type() != CV_32FC3) throw std::invalid_argument("estimate_noise_level: need CV_32FC3 display values");
  if (!mask.empty() && (mask.type() != CV_8U || mask.size() != display.size()))
    throw std::invalid_argument("estimate_noise_level: need a CV_8U mask of the photo's size");
  NoiseLevelFunction nlf;
  if (blocks_used) *blocks_used = 0;
  // Blocks start one pixel in: the operator's border rows are reflections.
  const int blocks_x = (display.cols - 2) / kNoiseBlockPx, blocks_y = (display.rows - 2) / kNoiseBlockPx;
  if (blocks_x < 1 || blocks_y < 1) return nlf;
  const cv::Mat response = immerkaer_response(display);
  // Per block and channel: its mean value and mean squared response, unless
  // it touches a clipped value or leaves the mask.
  std::array<std::array<std::vector<double>, kNoiseBins>, 3> per_bin;
  int used = 0;
  for (int by = 0; by < blocks_y; ++by)
    for (int bx = 0; bx < blocks_x; ++bx) {
      std::array<double, 3> sum{}, energy{};
      std::array<bool, 3> clipped{};
      bool outside = false;
      for (int r = 1 + by * kNoiseBlockPx; r < 1 + (by + 1) * kNoiseBlockPx; ++r) {
        const auto* v = display.ptr<cv::Vec3f>(r);
        const auto* e = response.ptr<cv::Vec3f>(r);
        const uint8_t* m = mask.empty() ? nullptr : mask.ptr<uint8_t>(r);
        for (int c = 1 + bx * kNoiseBlockPx; c < 1 + (bx + 1) * kNoiseBlockPx; ++c) {
          outside = outside || (m && !m[c]);
          for (int ch = 0; ch < 3; ++ch) {
            clipped[ch] = clipped[ch] || v[c][ch] <= kClipMargin || v[c][ch] >= 1.0f - kClipMargin;
            sum[ch] += v[c][ch];
            energy[ch] += static_cast<double>(e[c][ch]) * e[c][ch];
          }
        }
      }
      if (outside) continue;
      constexpr double kBlockArea = kNoiseBlockPx * kNoiseBlockPx;
      for (int ch = 0; ch < 3; ++ch) {
        const double value = sum[ch] / kBlockArea;
        const double sigma = std::sqrt(energy[ch] / kBlockArea) / kImmerkaerGain;
        if (clipped[ch] || !std::isfinite(value) || !std::isfinite(sigma)) continue;
        per_bin[ch][std::clamp(static_cast<int>(value * kNoiseBins), 0, kNoiseBins - 1)].push_back(sigma);
        if (ch == 1) ++used;
      }
    }
  bool any_bin = false;
  for (int ch = 0; ch < 3; ++ch) {
    std::array<bool, kNoiseBins> measured{};
    for (int b = 0; b < kNoiseBins; ++b)
      if (static_cast<int>(per_bin[ch][b].size()) >= kMinBlocksPerBin) {
        nlf.sigma[b][ch] = static_cast<float>(quantile(per_bin[ch][b], kEnvelopeQuantile) / kEnvelopeBias);
        measured[b] = any_bin = true;
      }
    // Bins without enough blocks take the nearest measured bin.
    for (int b = 0; b < kNoiseBins; ++b) {
      if (measured[b]) continue;
      for (int d = 1; d < kNoiseBins; ++d) {
        if (b - d >= 0 && measured[b - d]) { nlf.sigma[b][ch] = nlf.sigma[b - d][ch]; break; }
        if (b + d < kNoiseBins && measured[b + d]) { nlf.sigma[b][ch] = nlf.sigma[b + d][ch]; break; }
      }
    }
  }
  if (blocks_used) *blocks_used = any_bin ? used : 0;
  return nlf;
}

namespace {

// Edges are found on the display-encoded luminance, where a step's
// strength reads as a person sees it; they are measured on linear light.
cv::Mat edges_of(const cv::Mat& encoded) {
  cv::Mat edges;
  cv::Canny(encoded, edges, 20, 50, 3, true);
  return edges;
}

struct BlurReading {
  double sigma_px = 0.0;
  int edges = 0;  // 0: too few to tell
  bool through_noise = false;
};

constexpr uint8_t kNoBand = 255;

// edge_blur_of for every band of `band` (CV_8U: a band's index, kNoBand
// elsewhere) at once: one pass over the edges for all bands, and one more
// per re-blur width the wide bands ask for. A band too few edges tell
// reads 0 edges.
std::vector<BlurReading> band_edge_blurs(const cv::Mat& y, const cv::Mat& edges, const cv::Mat& band, int bands,
                                         int along_px, int min_edges = kMinBlurEdges) {
  min_edges = std::max(1, min_edges);
  const auto by_band = [&](const std::vector<double>& sigmas, const std::vector<cv::Point>& at) {
    std::vector<std::vector<double>> per(bands);
    for (size_t i = 0; i < sigmas.size(); ++i) per[band.at<uint8_t>(at[i])].push_back(sigmas[i]);
    return per;
  };
  std::vector<cv::Point> at;
  const std::vector<double> first = edge_blurs(y, edges, band != kNoBand, kReblurSigmaPx, along_px, &at);
  const std::vector<std::vector<double>> per = by_band(first, at);
  std::vector<BlurReading> out(bands);
  std::map<double, std::vector<int>> rereads;  // re-blur width: the bands that ask for it
  for (int b = 0; b < bands; ++b) {
    if (static_cast<int>(per[b].size()) < min_edges) continue;
    out[b] = {quantile(per[b], kEdgeQuantile), static_cast<int>(per[b].size()), along_px > 0};
    // A re-blur of about the edge's own width reads wide edges best.
    if (out[b].sigma_px > 1.5 * kReblurSigmaPx)
      rereads[std::round(std::min(out[b].sigma_px, 4.0) * 4.0) / 4.0].push_back(b);
  }
  for (const auto& [sigma0, which] : rereads) {
    cv::Mat mask = cv::Mat::zeros(band.size(), CV_8U);
    for (const int b : which) mask.setTo(255, band == b);
    at.clear();
    const std::vector<double> again = edge_blurs(y, edges, mask, sigma0, along_px, &at);
    const std::vector<std::vector<double>> per_again = by_band(again, at);
    for (const int b : which)
      if (static_cast<int>(per_again[b].size()) >= min_edges)
        out[b] = {quantile(per_again[b], kEdgeQuantile), static_cast<int>(per_again[b].size()), along_px > 0};
  }
  return out;
}

// The blur of the edges within `mask` (empty: all): their lower quartile.
// `edges`: edges_of the encoded luminance.
double edge_blur_of(const cv::Mat& y, const cv::Mat& edges, const cv::Mat& mask, int* edges_used, int min_edges,
                    int along_px = 0) {
  cv::Mat band(y.size(), CV_8U, cv::Scalar(0));
  if (!mask.empty()) band.setTo(kNoBand, mask == 0);
  const BlurReading reading = band_edge_blurs(y, edges, band, 1, along_px, min_edges).front();
  if (edges_used) *edges_used = reading.edges;
  return reading.sigma_px;
}

// Noise adds to an edge's gradient more than to its re-blurred gradient,
// Canny keeps the pixels where it added most, and the per-edge readings
// spread, which moves their lower quartile down: a noisy photo's edges read
// sharper than they are (4 levels of noise halved a 2 px blur). There the
// edges are found on the luminance smoothed a little, so that where they are
// does not depend on the noise, and each is read on the photo itself with
// its gradients summed along the edge. A known blur taken out in quadrature
// instead held on our test shapes but not on real photos, whose point spread
// is no Gaussian (docs/camera_match.md).
constexpr double kNoisyBlurFloor8bit = 0.9;  // levels of noise (the function's median) from which it biases
constexpr double kEdgeFindingBlurPx = 1.0;
constexpr int kAlongEdgePx = 3;

// A photo's edges, found once for every reading: on its own encoded
// luminance and, on a noisy photo, on that luminance smoothed by
// kEdgeFindingBlurPx.
struct EdgeFinding {
  const PhotoPlanes& planes;
  cv::Mat edges;
  cv::Mat smoothed_edges;  // empty for a clean photo
};

EdgeFinding edge_finding(const PhotoPlanes& planes, bool noisy) {
  EdgeFinding f{planes, edges_of(planes.encoded_luminance), {}};
  if (!noisy) return f;
  const int ksize = gaussian_ksize(kEdgeFindingBlurPx);
  cv::Mat smoothed;
  cv::GaussianBlur(planes.luminance, smoothed, {ksize, ksize}, kEdgeFindingBlurPx, kEdgeFindingBlurPx,
                   cv::BORDER_REFLECT);
  f.smoothed_edges = edges_of(encoded_luminance_of(smoothed));
  return f;
}

// Each band's blur (`band`: CV_8U, a band's index or kNoBand), read as a
// photo's is: a noisy photo through its noise, and the bands too few edges
// are found in so, directly.
std::vector<BlurReading> read_bands(const EdgeFinding& f, const cv::Mat& band, int bands) {
  if (f.smoothed_edges.empty()) return band_edge_blurs(f.planes.luminance, f.edges, band, bands, 0);
  std::vector<BlurReading> readings = band_edge_blurs(f.planes.luminance, f.smoothed_edges, band, bands, kAlongEdgePx);
  cv::Mat unread = band.clone();
  bool any_unread = false;
  for (int b = 0; b < bands; ++b) {
    if (readings[b].edges > 0) unread.setTo(kNoBand, band == b);
    else any_unread = true;
  }
  if (!any_unread) return readings;
  const std::vector<BlurReading> direct = band_edge_blurs(f.planes.luminance, f.edges, unread, bands, 0);
  for (int b = 0; b < bands; ++b)
    if (readings[b].edges == 0) readings[b] = direct[b];
  return readings;
}

// --- defocus ---------------------------------------------------------------

// Inverse depth (1/m) at the photo's size; 0 where there is no surface.
cv::Mat surface_dioptres(const cv::Mat& depth, cv::Size size) {
  cv::Mat d;
  if (depth.size() == size) d = depth;
  else cv::resize(depth, d, size, 0, 0, cv::INTER_NEAREST);
  cv::Mat u(size, CV_32F);
  for (int r = 0; r < size.height; ++r) {
    const float* z = d.ptr<float>(r);
    float* out = u.ptr<float>(r);
    for (int c = 0; c < size.width; ++c)
      out[c] = std::isfinite(z[c]) && z[c] > 0 && z[c] < kSkyDepthM ? 1.0f / z[c] : 0.0f;
  }
  return u;
}

// Bands of equal pixel count over the surfaces' inverse depth, each read for
// its blur as the whole photo is (read_bands; the bands too few edges tell
// are left out).
std::vector<DepthBandBlur> band_blurs(const EdgeFinding& f, const cv::Mat& dioptres) {
  std::vector<float> all;
  all.reserve(dioptres.total());
  for (int r = 0; r < dioptres.rows; ++r)
    for (const float* u = dioptres.ptr<float>(r); u != dioptres.ptr<float>(r) + dioptres.cols; ++u)
      if (*u > 0) all.push_back(*u);
  std::vector<DepthBandBlur> bands;
  if (all.size() < static_cast<size_t>(kDefocusBands * kMinBlurEdges)) return bands;
  // The values a sort would put at each band's start and middle, found by
  // nth_element on a shrinking range (a full sort of a megapixel's depths
  // costs more than reading the bands' blur).
  std::array<float, 2 * kDefocusBands> at{};  // at[k]: quantile k / (2 * kDefocusBands)
  auto from = all.begin();
  for (int k = 0; k < 2 * kDefocusBands; ++k) {
    const auto nth = all.begin() + static_cast<std::ptrdiff_t>(std::min(all.size() - 1, k * all.size() / (2 * kDefocusBands)));
    std::nth_element(from, nth, all.end());
    at[k] = *nth;
    from = nth;
  }
  // A band's lower limit; pixels of a depth repeated across limits go to
  // the last band starting there, and the bands before it stay empty.
  std::array<float, kDefocusBands> lower{};
  for (int b = 0; b < kDefocusBands; ++b) lower[b] = at[2 * b];
  cv::Mat band(dioptres.size(), CV_8U, cv::Scalar(kNoBand));
  for (int r = 0; r < dioptres.rows; ++r) {
    const float* u = dioptres.ptr<float>(r);
    uint8_t* out = band.ptr<uint8_t>(r);
    for (int c = 0; c < dioptres.cols; ++c)
      if (u[c] > 0) out[c] = static_cast<uint8_t>(std::upper_bound(lower.begin(), lower.end(), u[c]) - lower.begin() - 1);
  }
  const std::vector<BlurReading> readings = read_bands(f, band, kDefocusBands);
  for (int b = 0; b < kDefocusBands; ++b)
    if (readings[b].edges > 0) bands.push_back({at[2 * b + 1], readings[b].sigma_px, readings[b].edges});
  return bands;
}

// Grid steps over the focus's inverse depth, from 0 to 1.5x the nearest band's.
constexpr int kFocusSteps = 300;

// sigma_b^2 = base^2 + k^2 (u_b - u_f)^2 by least squares in sigma^2 for each
// focus on the grid (base^2, k^2 >= 0), the focus whose fit's sigmas are
// nearest the bands' kept; found when the photo shows defocus (kMinDefocus*).
Defocus fit_defocus(std::vector<DepthBandBlur> bands) {
  Defocus d;
  d.bands = std::move(bands);
  const std::vector<DepthBandBlur>& b = d.bands;
  if (static_cast<int>(b.size()) < kMinDefocusBands) return d;
  const double n = static_cast<double>(b.size());
  double mean_sigma = 0, lo_sigma = b[0].sigma_px;
  d.min_dioptres = d.max_dioptres = b[0].dioptres;
  for (const DepthBandBlur& band : b) {
    mean_sigma += band.sigma_px / n;
    lo_sigma = std::min(lo_sigma, band.sigma_px);
    d.min_dioptres = std::min(d.min_dioptres, band.dioptres);
    d.max_dioptres = std::max(d.max_dioptres, band.dioptres);
  }
  double single_rms = 0;
  for (const DepthBandBlur& band : b) single_rms += (band.sigma_px - mean_sigma) * (band.sigma_px - mean_sigma) / n;
  single_rms = std::sqrt(single_rms);
  double best_rms = std::numeric_limits<double>::infinity();
  for (int i = 0; i <= kFocusSteps; ++i) {
    const double uf = 1.5 * d.max_dioptres * i / kFocusSteps;
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (const DepthBandBlur& band : b) {
      const double x = (band.dioptres - uf) * (band.dioptres - uf), y = band.sigma_px * band.sigma_px;
      sx += x, sy += y, sxx += x * x, sxy += x * y;
    }
    const double det = n * sxx - sx * sx;
    double base2 = sy / n, k2 = 0;
    if (det > 1e-12) {
      k2 = (n * sxy - sx * sy) / det;
      base2 = (sy - k2 * sx) / n;
    }
    if (k2 < 0) k2 = 0, base2 = sy / n;
    if (base2 < 0) base2 = 0, k2 = sxx > 0 ? std::max(0.0, sxy / sxx) : 0.0;
    double rms = 0;
    for (const DepthBandBlur& band : b) {
      const double x = (band.dioptres - uf) * (band.dioptres - uf);
      const double e = std::sqrt(base2 + k2 * x) - band.sigma_px;
      rms += e * e / n;
    }
    rms = std::sqrt(rms);
    if (rms < best_rms) {
      best_rms = rms;
      d.focus_dioptres = uf;
      d.base_sigma_px = std::sqrt(base2);
      d.sigma_px_per_dioptre = std::sqrt(k2);
    }
  }
  double fit_lo = std::numeric_limits<double>::infinity(), fit_hi = 0;
  for (const DepthBandBlur& band : b) {
    const double s = d.sigma_at(1.0 / band.dioptres);
    fit_lo = std::min(fit_lo, s), fit_hi = std::max(fit_hi, s);
  }
  // Two bands at least must be the wider ones: one band alone is as likely
  // a few odd edges (a lamp's glow, a patch of soft texture) as a lens.
  const double wide = kMinDefocusRatio * std::max(lo_sigma, kMinMatchedBlurPx);
  const auto wide_bands = std::count_if(b.begin(), b.end(), [&](const DepthBandBlur& band) { return band.sigma_px >= wide; });
  d.found = fit_hi - fit_lo >= kMinDefocusRangePx && wide_bands >= kMinWideDefocusBands &&
            best_rms <= kMaxDefocusResidualShare * single_rms;
  return d;
}

}  // namespace

double Defocus::sigma_at(double depth_m) const {
  if (!(std::isfinite(depth_m) && depth_m > 0) || !(max_dioptres > 0)) return base_sigma_px;
  const double u = std::clamp(1.0 / depth_m, min_dioptres, max_dioptres);
  const double spread = sigma_px_per_dioptre * (u - focus_dioptres);
  return std::min(std::sqrt(base_sigma_px * base_sigma_px + spread * spread), kMaxBlurSigmaPx);
}

double PhotoImaging::blur_sigma_at(double depth_m) const {
  return defocus.found && std::isfinite(depth_m) && depth_m > 0 ? defocus.sigma_at(depth_m) : blur_sigma_px;
}

double estimate_edge_blur(const cv::Mat& linear, const cv::Mat& mask, int* edges_used, int min_edges) {
  if (linear.type() != CV_32F && linear.type() != CV_32FC3)
    throw std::invalid_argument("estimate_edge_blur: need CV_32F or CV_32FC3");
  const cv::Mat y = luminance_as_given(linear);
  return edge_blur_of(y, edges_of(encoded_luminance_of(y)), mask, edges_used, min_edges);
}

PhotoImaging estimate_photo_imaging(const cv::Mat& photo_srgb_linear, const cv::Mat& depth) {
  const auto start = Clock::now();
  if (photo_srgb_linear.type() != CV_32FC3 || photo_srgb_linear.empty())
    throw std::invalid_argument("estimate_photo_imaging: need a CV_32FC3 linear photo");
  if (!depth.empty() && depth.type() != CV_32F)
    throw std::invalid_argument("estimate_photo_imaging: the depth must be CV_32F metres");
  PhotoImaging out;
  const PhotoPlanes planes = photo_planes(photo_srgb_linear);
  out.noise = estimate_noise_level(planes.display, {}, &out.noise_blocks);
  out.noise_measured = out.noise_blocks > 0;
  const bool noisy = out.noise_measured && out.noise.median_8bit() >= kNoisyBlurFloor8bit;
  const EdgeFinding finding = edge_finding(planes, noisy);
  const BlurReading blur = read_bands(finding, cv::Mat::zeros(photo_srgb_linear.size(), CV_8U), 1).front();
  out.blur_measured = blur.edges > 0;
  out.blur_sigma_px = blur.sigma_px;
  out.blur_edges = blur.edges;
  out.blur_read_through_noise = blur.through_noise;
  if (out.blur_measured && !depth.empty())
    out.defocus = fit_defocus(band_blurs(finding, surface_dioptres(depth, photo_srgb_linear.size())));
  out.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return out;
}

cv::Mat blur_change(const cv::Mat& photo_linear, const cv::Mat& composite_linear, const cv::Mat& coverage,
                    double sigma_px, cv::Mat* blurred_coverage_out) {
  if (photo_linear.size() != composite_linear.size() || photo_linear.type() != CV_32FC3 ||
      composite_linear.type() != CV_32FC3 || coverage.size() != photo_linear.size() || coverage.type() != CV_32F)
    throw std::invalid_argument("blur_change: need CV_32FC3 photo and composite and a CV_32F coverage of one size");
  cv::Mat out = composite_linear.clone();
  if (blurred_coverage_out) *blurred_coverage_out = coverage.clone();
  if (!(sigma_px > 0)) return out;
  // Where the prop or its change is, grown by the kernel's reach: the only
  // pixels the blur can move. Full-frame temporaries are avoided here and
  // below: at 1024x768 their page faults cost more than the blur.
  const cv::Rect changed = changed_bounds(photo_linear, composite_linear, coverage);
  if (changed.empty()) return out;
  const int ksize = gaussian_ksize(sigma_px), reach = ksize / 2;
  const cv::Rect window =
      (changed + cv::Size(2 * reach, 2 * reach) - cv::Point(reach, reach)) & cv::Rect({0, 0}, photo_linear.size());
  const cv::Mat photo = photo_linear(window), cover = coverage(window), composite = composite_linear(window);
  // The prop's layer over the photo: its own pixels premultiplied by their
  // coverage plus the change it makes to the rest (zero beyond `changed`, so
  // the window's replicated border adds nothing).
  cv::Mat layer(window.size(), CV_32FC3);
  for (int r = 0; r < window.height; ++r) {
    const auto* p = photo.ptr<cv::Vec3f>(r);
    const auto* c = composite.ptr<cv::Vec3f>(r);
    const float* m = cover.ptr<float>(r);
    auto* l = layer.ptr<cv::Vec3f>(r);
    for (int x = 0; x < window.width; ++x) l[x] = c[x] - p[x] * (1.0f - m[x]);
  }
  cv::Mat blurred_coverage;
  cv::GaussianBlur(layer, layer, {ksize, ksize}, sigma_px, sigma_px, cv::BORDER_REPLICATE);
  cv::GaussianBlur(cover, blurred_coverage, {ksize, ksize}, sigma_px, sigma_px, cv::BORDER_REPLICATE);
  // The blurred layer over the photo, seen through the blurred coverage;
  // pixels neither reaches keep the composite's exact value.
  cv::Mat target = out(window);
  for (int r = 0; r < window.height; ++r) {
    const auto* p = photo.ptr<cv::Vec3f>(r);
    const auto* l = layer.ptr<cv::Vec3f>(r);
    const float* m = blurred_coverage.ptr<float>(r);
    auto* o = target.ptr<cv::Vec3f>(r);
    for (int x = 0; x < window.width; ++x) {
      if (m[x] == 0 && l[x] == cv::Vec3f()) continue;
      const cv::Vec3f v = p[x] * (1.0f - m[x]) + l[x];
      o[x] = {std::max(v[0], 0.0f), std::max(v[1], 0.0f), std::max(v[2], 0.0f)};
    }
  }
  if (blurred_coverage_out) blurred_coverage.copyTo((*blurred_coverage_out)(window));
  return out;
}

std::array<float, 3> region_noise_sigma(const cv::Mat& display, const cv::Mat& mask, int* pixels) {
  if (display.type() != CV_32FC3 || mask.type() != CV_8U || mask.size() != display.size())
    throw std::invalid_argument("region_noise_sigma: need CV_32FC3 display values and a CV_8U mask of its size");
  std::array<float, 3> sigma{};
  const int n = cv::countNonZero(mask);
  if (pixels) *pixels = n;
  if (n < kMinRegionNoisePixels) return sigma;
  std::vector<cv::Mat> channels;
  cv::split(display, channels);
  for (int ch = 0; ch < 3; ++ch) {
    const cv::Mat response = immerkaer_response(channels[ch]);
    std::vector<double> magnitudes;
    magnitudes.reserve(static_cast<size_t>(n));
    for (int r = 0; r < display.rows; ++r)
      for (int c = 0; c < display.cols; ++c)
        if (mask.at<uint8_t>(r, c)) magnitudes.push_back(std::abs(response.at<float>(r, c)));
    sigma[ch] = static_cast<float>(kMadToSigma * quantile(magnitudes, 0.5) / kImmerkaerGain);
  }
  return sigma;
}

cv::Mat add_matched_noise(const cv::Mat& display, const cv::Mat& coverage, const NoiseLevelFunction& photo_noise,
                          uint64_t seed, CameraMatchReport* report) {
  if (display.type() != CV_32FC3 || coverage.type() != CV_32F || display.size() != coverage.size())
    throw std::invalid_argument("add_matched_noise: need CV_32FC3 display values and a CV_32F coverage of its size");
  // What the render already put on the prop: measured on its inside, away from the silhouette.
  cv::Mat inside = coverage >= 0.999f;
  cv::erode(inside, inside, cv::Mat(), {-1, -1}, 2);
  const std::array<float, 3> own = region_noise_sigma(display, inside);
  cv::Mat out = display.clone();
  double added_sum = 0;
  long added_pixels = 0;
  for (int r = 0; r < display.rows; ++r) {
    const float* m = coverage.ptr<float>(r);
    auto* px = out.ptr<cv::Vec3f>(r);
    for (int c = 0; c < display.cols; ++c) {
      if (!(m[c] > 0)) continue;
      double pixel_sigma = 0;
      for (int ch = 0; ch < 3; ++ch) {
        const float target = photo_noise.at(ch, px[c][ch]);
        const float sigma = std::sqrt(std::max(0.0f, target * target - own[ch] * own[ch] - kQuantisationVariance));
        px[c][ch] = std::clamp(px[c][ch] + std::min(1.0f, m[c]) * sigma * hashed_gaussian(seed, c, r, ch), 0.0f, 1.0f);
        pixel_sigma += sigma / 3.0;
      }
      added_sum += pixel_sigma;
      ++added_pixels;
    }
  }
  if (report) {
    report->noise_added_8bit = added_pixels ? 255.0 * added_sum / added_pixels : 0.0;
    report->prop_noise_8bit = 255.0 * (own[0] + own[1] + own[2]) / 3.0;
  }
  return out;
}

cv::Mat match_camera(const cv::Mat& photo_linear, const cv::Mat& composite_linear, const cv::Mat& coverage,
                     const PhotoImaging& imaging, const CameraMatchOptions& options, double response_gamma,
                     CameraMatchReport* report) {
  const auto start = Clock::now();
  CameraMatchReport local;
  CameraMatchReport& rep = report ? *report : local;
  rep = {};
  char text[200];
  cv::Mat out = composite_linear;
  cv::Mat prop_coverage = coverage.empty() ? cv::Mat::zeros(composite_linear.size(), CV_32F) : coverage;

  CameraMatchStep blur{"blur", false, ""};
  // A photo whose blur grows with depth gives the prop its own depth's.
  const bool by_depth = imaging.defocus.found && options.prop_depth_m > 0 && std::isfinite(options.prop_depth_m);
  const double sigma = imaging.blur_sigma_at(options.prop_depth_m);
  char where[96] = "";
  if (by_depth)
    std::snprintf(where, sizeof where, " at the prop's depth %.2f m (defocus, focus at %.2f m)", options.prop_depth_m,
                  imaging.defocus.focus_dioptres > 0 ? 1.0 / imaging.defocus.focus_dioptres : INFINITY);
  if (!options.blur) {
    blur.why = "turned off";
  } else if (!imaging.blur_measured) {
    blur.why = "too few isolated edges in the photo to measure its blur";
  } else if (sigma < kMinMatchedBlurPx) {
    std::snprintf(text, sizeof text, "photo as sharp as the render (edge sigma %.2f px < %.2f%s)", sigma,
                  kMinMatchedBlurPx, where);
    blur.why = text;
  } else {
    cv::Mat blurred_coverage;
    out = blur_change(photo_linear, out, prop_coverage, sigma, &blurred_coverage);
    prop_coverage = blurred_coverage;  // a new buffer: the caller's coverage stays as rendered
    rep.blur_sigma_px = sigma;
    blur.applied = true;
    if (by_depth)
      std::snprintf(text, sizeof text, "photo edges blurred by sigma %.2f px%s", sigma, where);
    else
      std::snprintf(text, sizeof text, "photo edges blurred by sigma %.2f px (lower quartile of %d edge pixels)",
                    sigma, imaging.blur_edges);
    blur.why = text;
  }
  rep.steps.push_back(blur);

  // The lens darkened the photo toward its corners: the prop gets the same
  // (after the blur, which commutes with a fall-off this smooth; before the
  // sensor's noise, whose level follows the darkened value).
  CameraMatchStep vignette{"vignette", false, ""};
  if (!options.vignetting.known()) {
    vignette.why = "no calibrated vignetting (one photo cannot tell a lens's fall-off from the scene's)";
  } else if (const std::string problem = vignetting_problem(options.vignetting); !problem.empty()) {
    vignette.why = "calibrated vignetting unusable: " + problem;
  } else if (const cv::Rect covered = covered_bounds(prop_coverage); covered.empty()) {
    vignette.why = "the prop covers no pixel";
  } else {
    // What the prop adds, rendered from the scene inferred with the lens
    // divided out: the lens's fall-off on all of it.
    if (out.data == composite_linear.data) out = out.clone();  // never the caller's buffer
    vignette_prop(photo_linear, out, prop_coverage, options.vignetting);
    rep.vignette_gain = options.vignetting.at_pixel(covered.x + 0.5 * covered.width - 0.5,
                                                    covered.y + 0.5 * covered.height - 0.5, out.size());
    vignette.applied = true;
    std::snprintf(text, sizeof text, "lens fall-off %.2f at the prop, %.2f in the corners (%s)", rep.vignette_gain,
                  options.vignetting.at_radius(1.0),
                  options.vignetting_source.empty() ? "calibration" : options.vignetting_source.c_str());
    vignette.why = text;
  }
  rep.steps.push_back(vignette);

  CameraMatchStep noise{"noise", false, ""};
  const double level = imaging.noise_measured ? imaging.noise.median_8bit() : 0.0;
  if (!options.noise) {
    noise.why = "turned off";
  } else if (!imaging.noise_measured) {
    noise.why = "too few flat unclipped blocks in the photo to measure its noise";
  } else if (level < kMinMatchedNoise8bit) {
    std::snprintf(text, sizeof text, "photo as clean as an 8-bit render (noise %.2f levels < %.2f)", level,
                  kMinMatchedNoise8bit);
    noise.why = text;
  } else if (const cv::Rect covered = covered_bounds(prop_coverage); covered.empty()) {
    noise.why = "the prop covers no pixel";
  } else {
    // Display values of the matched composite around the prop, noise added
    // on its pixels only, and back; every other pixel keeps its exact value.
    const cv::Rect roi = (covered + cv::Size(8, 8) - cv::Point(4, 4)) & cv::Rect({0, 0}, out.size());
    const cv::Mat display = to_display(capture::response_linear_to_srgb_linear(out(roi), response_gamma));
    const cv::Mat noisy = add_matched_noise(display, prop_coverage(roi), imaging.noise, options.seed, &rep);
    const cv::Mat matched = capture::srgb_linear_to_response_linear(to_srgb_linear(noisy), response_gamma);
    if (out.data == composite_linear.data) out = out.clone();  // never the caller's buffer
    cv::Mat target = out(roi);
    matched.copyTo(target, prop_coverage(roi) > 0);
    noise.applied = true;
    std::snprintf(text, sizeof text, "photo noise %.1f levels (median); %.1f added to the prop (its render noise %.1f)",
                  level, rep.noise_added_8bit, rep.prop_noise_8bit);
    noise.why = text;
  }
  rep.steps.push_back(noise);
  rep.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return out;
}

}  // namespace propcam::render
