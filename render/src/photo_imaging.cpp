#include "propcam/render/photo_imaging.h"

#include <opencv2/imgproc.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <mutex>
#include <numbers>
#include <stdexcept>

#include "luminance.h"
#include "propcam/capture/image_file.h"

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
    const int n = 96, centre = n / 2;
    const int ksize = gaussian_ksize(sigma0);
    const cv::Mat kernel = cv::getGaussianKernel(ksize, sigma0, CV_64F);
    const int entries = static_cast<int>(std::lround(kMaxBlurSigmaPx / kBlurTableStepPx)) + 1;
    for (int entry = 0; entry < entries; ++entry) {
      const double sigma = entry * kBlurTableStepPx;
      double sum = 0;
      for (int p = 0; p < kBlurTablePhases; ++p) {
        const double phase = centre + (p + 0.5) / kBlurTablePhases - 0.5;
        std::vector<double> v(n), w(n, 0.0);
        for (int i = 0; i < n; ++i) v[i] = blurred_step_pixel(i, phase, sigma);
        for (int i = 0; i < n; ++i)
          for (int k = 0; k < ksize; ++k) w[i] += kernel.at<double>(k) * v[std::clamp(i + k - ksize / 2, 0, n - 1)];
        int best = 1;
        for (int i = 1; i < n - 1; ++i)
          if (v[i + 1] - v[i - 1] > v[best + 1] - v[best - 1]) best = i;
        sum += (v[best + 1] - v[best - 1]) / std::max(kTinyDifference, w[best + 1] - w[best - 1]);
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

cv::Mat luminance_of(const cv::Mat& linear) {
  if (linear.type() == CV_32F) return linear;
  if (linear.type() != CV_32FC3) throw std::invalid_argument("estimate_edge_blur: need CV_32F or CV_32FC3");
  cv::Mat y(linear.size(), CV_32F);
  for (int r = 0; r < linear.rows; ++r) {
    const auto* in = linear.ptr<cv::Vec3f>(r);
    auto* out = y.ptr<float>(r);
    for (int c = 0; c < linear.cols; ++c) out[c] = std::max(0.0f, detail::luminance(in[c]));
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

// The blur at each isolated edge pixel, re-blurred with sigma0.
std::vector<double> edge_blurs(const cv::Mat& y, const cv::Mat& edges, const cv::Mat& mask, double sigma0) {
  const ReblurTable& table = reblur_table(sigma0);
  const int ksize = gaussian_ksize(sigma0);
  cv::Mat reblurred, gx, gy, gx1, gy1;
  cv::GaussianBlur(y, reblurred, {ksize, ksize}, sigma0, sigma0, cv::BORDER_REFLECT);
  cv::Sobel(y, gx, CV_32F, 1, 0, 3);
  cv::Sobel(y, gy, CV_32F, 0, 1, 3);
  cv::Sobel(reblurred, gx1, CV_32F, 1, 0, 3);
  cv::Sobel(reblurred, gy1, CV_32F, 0, 1, 3);
  const int border = kProfileHalfPx + ksize / 2 + 2;
  std::vector<double> sigmas;
  for (int r = border; r < y.rows - border; ++r)
    for (int c = border; c < y.cols - border; ++c) {
      if (!edges.at<uint8_t>(r, c) || (!mask.empty() && !mask.at<uint8_t>(r, c))) continue;
      const float ax = gx.at<float>(r, c), ay = gy.at<float>(r, c);
      const float g = std::hypot(ax, ay);
      if (!(g > 0)) continue;
      const float nx = ax / g, ny = ay / g;
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
      const float g1 = std::hypot(gx1.at<float>(r, c), gy1.at<float>(r, c));
      if (!(g1 > 0)) continue;
      sigmas.push_back(table.sigma_for(g / g1));
    }
  return sigmas;
}

// Display values (the sRGB curve) of linear sRGB clamped to [0, 1], and back.
cv::Mat to_display(const cv::Mat& srgb_linear) {
  cv::Mat display(srgb_linear.size(), CV_32FC3);
  for (int r = 0; r < display.rows; ++r) {
    const auto* in = srgb_linear.ptr<cv::Vec3f>(r);
    auto* o = display.ptr<cv::Vec3f>(r);
    for (int c = 0; c < display.cols; ++c)
      for (int k = 0; k < 3; ++k) o[c][k] = capture::linear_to_srgb(std::clamp(in[c][k], 0.0f, 1.0f));
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

// CV_8U: 255 where any channel is non-zero.
cv::Mat nonzero(const cv::Mat& image) {
  std::vector<cv::Mat> channels;
  cv::split(image, channels);
  cv::Mat any = channels[0] != 0;
  for (size_t k = 1; k < channels.size(); ++k) any |= channels[k] != 0;
  return any;
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
  std::vector<cv::Mat> channels;
  cv::split(display, channels);
  NoiseLevelFunction nlf;
  int used = 0;
  std::array<bool, kNoiseBins> any_bin{};
  // Each block's mean value, mean squared response, clipped share and share
  // inside the mask, by area averaging; blocks start one pixel in (the
  // operator's border rows are reflections).
  const int blocks_x = (display.cols - 2) / kNoiseBlockPx, blocks_y = (display.rows - 2) / kNoiseBlockPx;
  if (blocks_x < 1 || blocks_y < 1) {
    if (blocks_used) *blocks_used = 0;
    return nlf;
  }
  const cv::Rect area(1, 1, blocks_x * kNoiseBlockPx, blocks_y * kNoiseBlockPx);
  const auto block_means = [&](const cv::Mat& m) {
    cv::Mat out;
    cv::resize(m(area), out, {blocks_x, blocks_y}, 0, 0, cv::INTER_AREA);
    return out;
  };
  cv::Mat inside_share;
  if (!mask.empty()) {
    cv::Mat inside;
    cv::Mat(mask != 0).convertTo(inside, CV_32F, 1.0 / 255.0);
    inside_share = block_means(inside);
  }
  for (int ch = 0; ch < 3; ++ch) {
    const cv::Mat response = immerkaer_response(channels[ch]);
    std::array<std::vector<double>, kNoiseBins> per_bin;
    cv::Mat clipped;
    const cv::Mat clipped_8u = (channels[ch] <= kClipMargin) | (channels[ch] >= 1.0f - kClipMargin);
    clipped_8u.convertTo(clipped, CV_32F, 1.0 / 255.0);
    const cv::Mat mean = block_means(channels[ch]), energy = block_means(response.mul(response)),
                  clipped_share = block_means(clipped);
    for (int by = 0; by < blocks_y; ++by)
      for (int bx = 0; bx < blocks_x; ++bx) {
        if (clipped_share.at<float>(by, bx) > 0) continue;
        if (!inside_share.empty() && inside_share.at<float>(by, bx) < 1.0f - 1e-4f) continue;
        const double value = mean.at<float>(by, bx);
        const double sigma = std::sqrt(std::max(0.0f, energy.at<float>(by, bx))) / kImmerkaerGain;
        if (!std::isfinite(value) || !std::isfinite(sigma)) continue;
        const int bin = std::clamp(static_cast<int>(value * kNoiseBins), 0, kNoiseBins - 1);
        per_bin[bin].push_back(sigma);
        if (ch == 1) ++used;
      }
    std::array<bool, kNoiseBins> measured{};
    for (int b = 0; b < kNoiseBins; ++b)
      if (static_cast<int>(per_bin[b].size()) >= kMinBlocksPerBin) {
        nlf.sigma[b][ch] = static_cast<float>(quantile(per_bin[b], kEnvelopeQuantile) / kEnvelopeBias);
        measured[b] = any_bin[b] = true;
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
  if (blocks_used) *blocks_used = std::any_of(any_bin.begin(), any_bin.end(), [](bool b) { return b; }) ? used : 0;
  return nlf;
}

double estimate_edge_blur(const cv::Mat& linear, const cv::Mat& mask, int* edges_used, int min_edges) {
  const cv::Mat y = luminance_of(linear);
  // Edges are found on the display-encoded luminance, where a step's
  // strength reads as a person sees it; they are measured on linear light.
  cv::Mat encoded(y.size(), CV_8U);
  for (int r = 0; r < y.rows; ++r)
    for (int c = 0; c < y.cols; ++c)
      encoded.at<uint8_t>(r, c) = cv::saturate_cast<uint8_t>(255.0f * capture::linear_to_srgb(std::min(1.0f, y.at<float>(r, c))));
  cv::Mat edges;
  cv::Canny(encoded, edges, 20, 50, 3, true);
  std::vector<double> sigmas = edge_blurs(y, edges, mask, kReblurSigmaPx);
  if (static_cast<int>(sigmas.size()) < std::max(1, min_edges)) {
    if (edges_used) *edges_used = 0;
    return 0.0;
  }
  double sigma = quantile(sigmas, kEdgeQuantile);
  // A re-blur of about the edge's own width reads wide edges best.
  if (sigma > 1.5 * kReblurSigmaPx) {
    const double sigma0 = std::round(std::min(sigma, 4.0) * 4.0) / 4.0;
    std::vector<double> again = edge_blurs(y, edges, mask, sigma0);
    if (static_cast<int>(again.size()) >= std::max(1, min_edges)) sigmas = std::move(again);
    sigma = quantile(sigmas, kEdgeQuantile);
  }
  if (edges_used) *edges_used = static_cast<int>(sigmas.size());
  return sigma;
}

PhotoImaging estimate_photo_imaging(const cv::Mat& photo_srgb_linear) {
  const auto start = Clock::now();
  if (photo_srgb_linear.type() != CV_32FC3 || photo_srgb_linear.empty())
    throw std::invalid_argument("estimate_photo_imaging: need a CV_32FC3 linear photo");
  PhotoImaging out;
  // Non-finite values as black, the rest within [0, 1]: both estimates read this.
  cv::Mat linear = photo_srgb_linear.clone();
  cv::patchNaNs(linear, 0.0);
  linear = cv::min(cv::max(linear, 0.0), 1.0);
  out.noise = estimate_noise_level(to_display(linear), {}, &out.noise_blocks);
  out.noise_measured = out.noise_blocks > 0;
  out.blur_sigma_px = estimate_edge_blur(linear, {}, &out.blur_edges);
  out.blur_measured = out.blur_edges > 0;
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
  // pixels the blur can move.
  const cv::Rect changed = cv::boundingRect(nonzero(composite_linear - photo_linear) | (coverage != 0));
  if (changed.empty()) return out;
  const int ksize = gaussian_ksize(sigma_px), reach = ksize / 2;
  const cv::Rect window =
      (changed + cv::Size(2 * reach, 2 * reach) - cv::Point(reach, reach)) & cv::Rect({0, 0}, photo_linear.size());
  const cv::Mat photo = photo_linear(window), cover = coverage(window);
  // The prop's layer over the photo: its own pixels premultiplied by their
  // coverage plus the change it makes to the rest (zero beyond `changed`, so
  // the window's replicated border adds nothing).
  cv::Mat uncovered_here;
  cv::merge(std::vector<cv::Mat>(3, 1.0f - cover), uncovered_here);
  const cv::Mat layer = composite_linear(window) - photo.mul(uncovered_here);
  cv::Mat blurred_layer, blurred_coverage;
  cv::GaussianBlur(layer, blurred_layer, {ksize, ksize}, sigma_px, sigma_px, cv::BORDER_REPLICATE);
  cv::GaussianBlur(cover, blurred_coverage, {ksize, ksize}, sigma_px, sigma_px, cv::BORDER_REPLICATE);
  // The blurred layer over the photo, seen through the blurred coverage.
  cv::Mat uncovered;
  cv::merge(std::vector<cv::Mat>(3, 1.0f - blurred_coverage), uncovered);
  cv::Mat region = photo.mul(uncovered) + blurred_layer;
  region = cv::max(region, 0.0);
  // Pixels neither the blurred layer nor the blurred coverage reaches keep the photo's exact value.
  cv::Mat target = out(window);
  region.copyTo(target, nonzero(blurred_layer) | (blurred_coverage != 0));
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
  char text[160];
  cv::Mat out = composite_linear;
  cv::Mat prop_coverage = coverage.empty() ? cv::Mat::zeros(composite_linear.size(), CV_32F) : coverage;

  CameraMatchStep blur{"blur", false, ""};
  if (!options.blur) {
    blur.why = "turned off";
  } else if (!imaging.blur_measured) {
    blur.why = "too few isolated edges in the photo to measure its blur";
  } else if (imaging.blur_sigma_px < kMinMatchedBlurPx) {
    std::snprintf(text, sizeof text, "photo as sharp as the render (edge sigma %.2f px < %.2f)", imaging.blur_sigma_px,
                  kMinMatchedBlurPx);
    blur.why = text;
  } else {
    cv::Mat blurred_coverage;
    out = blur_change(photo_linear, out, prop_coverage, imaging.blur_sigma_px, &blurred_coverage);
    prop_coverage = blurred_coverage;  // a new buffer: the caller's coverage stays as rendered
    rep.blur_sigma_px = imaging.blur_sigma_px;
    blur.applied = true;
    std::snprintf(text, sizeof text, "photo edges blurred by sigma %.2f px (lower quartile of %d edge pixels)",
                  imaging.blur_sigma_px, imaging.blur_edges);
    blur.why = text;
  }
  rep.steps.push_back(blur);

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
  } else if (cv::countNonZero(prop_coverage > 0) == 0) {
    noise.why = "the prop covers no pixel";
  } else {
    // Display values of the matched composite around the prop, noise added
    // on its pixels only, and back; every other pixel keeps its exact value.
    cv::Rect roi = cv::boundingRect(prop_coverage > 0);
    roi = (roi + cv::Size(8, 8) - cv::Point(4, 4)) & cv::Rect({0, 0}, out.size());
    const cv::Mat display = to_display(capture::response_linear_to_srgb_linear(out(roi), response_gamma));
    const cv::Mat noisy = add_matched_noise(display, prop_coverage(roi), imaging.noise, options.seed, &rep);
    const cv::Mat matched = capture::srgb_linear_to_response_linear(to_srgb_linear(noisy), response_gamma);
    out = out.clone();
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
