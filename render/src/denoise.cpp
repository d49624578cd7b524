#include "propcam/render/denoise.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "luminance.h"

namespace propcam::render {
namespace {

// Albedo channels below this are not divided out (sky, black surfaces): the
// illumination would blow up and carry the noise of a near-zero divisor.
constexpr float kMinAlbedo = 0.02f;
// Floor of the luminance scale, so a pixel with zero estimated variance keeps
// its value instead of dividing by zero.
constexpr double kMinLuminanceScale = 1e-6;
// Floor of the depth scale (metres), for depth 0 (nothing hit).
constexpr double kMinDepthScale = 1e-4;
// The B3-spline à-trous kernel.
constexpr std::array<float, 5> kKernel = {1.f / 16, 1.f / 4, 3.f / 8, 1.f / 4, 1.f / 16};
constexpr int kMaxLevels = 10;

using detail::luminance;

cv::Vec3f modulation(const cv::Vec3f& albedo) {
  cv::Vec3f m;
  for (int c = 0; c < 3; ++c) m[c] = std::isfinite(albedo[c]) && albedo[c] >= kMinAlbedo ? albedo[c] : 1.f;
  return m;
}

bool is_partial(float coverage) { return coverage > 0.f && coverage < 1.f; }

void check_inputs(const ChangeBuffer& input, const cv::Mat& touched, const cv::Mat& coverage, const DenoiseGuides& g,
                  const DenoiseOptions& o) {
  const cv::Size size = input.change.size();
  const auto fits = [&](const cv::Mat& m, int type) { return m.type() == type && m.size() == size; };
  if (input.change.type() != CV_32FC3) throw std::invalid_argument("denoise: change must be CV_32FC3");
  if (!fits(input.variance, CV_32F) || !fits(touched, CV_8U) || !fits(coverage, CV_32F))
    throw std::invalid_argument("denoise: variance, touched and coverage must match the change's size (CV_32F, CV_8U, CV_32F)");
  if (!fits(g.albedo, CV_32FC3) || !fits(g.normal, CV_32FC3) || !fits(g.depth, CV_32F) || !fits(g.prop, CV_8U))
    throw std::invalid_argument("denoise: guides must match the change's size (albedo, normal CV_32FC3; depth CV_32F; prop CV_8U)");
  if (o.levels < 0 || o.levels > kMaxLevels) throw std::invalid_argument("denoise: levels must be in 0..10");
  if (!(o.luminance_sigma > 0) || !(o.normal_power >= 0) || !(o.depth_sigma > 0) || !std::isfinite(o.luminance_sigma) ||
      !std::isfinite(o.normal_power) || !std::isfinite(o.depth_sigma))
    throw std::invalid_argument("denoise: sigmas must be positive and finite");
}

// Weight of neighbour q for pixel p, without the kernel and luminance terms.
float geometry_weight(const DenoiseGuides& g, const cv::Mat& coverage, cv::Point p, cv::Point q,
                      const DenoiseOptions& o) {
  if (g.prop.at<uint8_t>(p) != g.prop.at<uint8_t>(q) || is_partial(coverage.at<float>(q))) return 0.f;
  const cv::Vec3f np = g.normal.at<cv::Vec3f>(p), nq = g.normal.at<cv::Vec3f>(q);
  const float cos_n = np.dot(nq);
  const bool p_hit = np.dot(np) > 0.f, q_hit = nq.dot(nq) > 0.f;
  if (p_hit != q_hit) return 0.f;
  const float w_normal = p_hit ? static_cast<float>(std::pow(std::max(0.f, cos_n), o.normal_power)) : 1.f;
  const double zp = g.depth.at<float>(p), zq = g.depth.at<float>(q);
  const double pixels_apart = std::max(std::abs(p.x - q.x), std::abs(p.y - q.y));
  const double scale = std::max(kMinDepthScale, o.depth_sigma * std::abs(zp) * pixels_apart);
  const float w_depth = static_cast<float>(std::exp(-std::abs(zp - zq) / scale));
  return w_normal * w_depth;
}

}  // namespace

cv::Mat denoise_change(const ChangeBuffer& input, const cv::Mat& touched, const cv::Mat& coverage,
                       const DenoiseGuides& guides, const DenoiseOptions& options) {
  check_inputs(input, touched, coverage, guides, options);
  const int rows = input.change.rows, cols = input.change.cols;
  // Illumination and its luminance variance, everywhere (untouched pixels are exact zeros).
  cv::Mat illumination(rows, cols, CV_32FC3), variance(rows, cols, CV_32F);
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < cols; ++x) {
      const cv::Vec3f m = modulation(guides.albedo.at<cv::Vec3f>(y, x));
      const cv::Vec3f c = input.change.at<cv::Vec3f>(y, x);
      illumination.at<cv::Vec3f>(y, x) = cv::Vec3f(c[0] / m[0], c[1] / m[1], c[2] / m[2]);
      const float lm = luminance(m), v = input.variance.at<float>(y, x);
      variance.at<float>(y, x) = std::isfinite(v) && v > 0.f ? v / (lm * lm) : 0.f;
    }
  cv::Mat current = illumination.clone(), next_values = current.clone(), next_variance = variance.clone();
  for (int level = 0; level < options.levels; ++level) {
    const int step = 1 << level;
    cv::Mat smoothed_variance;
    cv::GaussianBlur(variance, smoothed_variance, cv::Size(3, 3), 0.0, 0.0, cv::BORDER_REPLICATE);
    for (int y = 0; y < rows; ++y)
      for (int x = 0; x < cols; ++x) {
        const cv::Point p(x, y);
        if (!touched.at<uint8_t>(p) || is_partial(coverage.at<float>(p))) continue;
        const cv::Vec3f vp = current.at<cv::Vec3f>(p);
        const float lp = luminance(vp);
        const double luminance_scale =
            std::max(kMinLuminanceScale, options.luminance_sigma * std::sqrt(std::max(0.f, smoothed_variance.at<float>(p))));
        cv::Vec3f sum(0.f, 0.f, 0.f);
        float weight_sum = 0.f, variance_sum = 0.f;
        for (int j = -2; j <= 2; ++j)
          for (int i = -2; i <= 2; ++i) {
            const cv::Point q(x + i * step, y + j * step);
            if (q.x < 0 || q.y < 0 || q.x >= cols || q.y >= rows) continue;
            const cv::Vec3f vq = current.at<cv::Vec3f>(q);
            float w = kKernel[i + 2] * kKernel[j + 2];
            if (i != 0 || j != 0) {
              w *= geometry_weight(guides, coverage, p, q, options);
              w *= static_cast<float>(std::exp(-std::abs(lp - luminance(vq)) / luminance_scale));
            }
            if (!(w > 0.f)) continue;
            sum += w * vq;
            weight_sum += w;
            variance_sum += w * w * variance.at<float>(q);
          }
        next_values.at<cv::Vec3f>(p) = sum / weight_sum;  // the centre's weight is positive
        next_variance.at<float>(p) = variance_sum / (weight_sum * weight_sum);
      }
    next_values.copyTo(current);
    next_variance.copyTo(variance);
  }
  cv::Mat out = input.change.clone();
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < cols; ++x) {
      if (!touched.at<uint8_t>(y, x) || is_partial(coverage.at<float>(y, x))) continue;
      const cv::Vec3f m = modulation(guides.albedo.at<cv::Vec3f>(y, x));
      const cv::Vec3f v = current.at<cv::Vec3f>(y, x);
      const cv::Vec3f filtered(v[0] * m[0], v[1] * m[1], v[2] * m[2]);
      if (std::isfinite(filtered[0]) && std::isfinite(filtered[1]) && std::isfinite(filtered[2]))
        out.at<cv::Vec3f>(y, x) = filtered;
    }
  return out;
}

std::vector<bool> filter_helps_per_tile(const cv::Mat& a, const cv::Mat& a_filtered, const cv::Mat& b,
                                        const cv::Mat& touched, const std::vector<cv::Rect>& tiles) {
  if (a.type() != CV_32FC3 || a_filtered.type() != CV_32FC3 || b.type() != CV_32FC3 || touched.type() != CV_8U ||
      a.size() != a_filtered.size() || a.size() != b.size() || a.size() != touched.size())
    throw std::invalid_argument("filter_helps_per_tile: buffers must be CV_32FC3 (touched CV_8U) of one size");
  const cv::Rect image(0, 0, a.cols, a.rows);
  std::vector<bool> helps;
  helps.reserve(tiles.size());
  for (const cv::Rect& tile : tiles) {
    const cv::Rect r = tile & image;
    double filtered_error = 0.0, raw_error = 0.0;
    for (int y = r.y; y < r.br().y; ++y)
      for (int x = r.x; x < r.br().x; ++x) {
        if (!touched.at<uint8_t>(y, x)) continue;
        const cv::Vec3f vb = b.at<cv::Vec3f>(y, x);
        const cv::Vec3f df = a_filtered.at<cv::Vec3f>(y, x) - vb, dr = a.at<cv::Vec3f>(y, x) - vb;
        filtered_error += df.dot(df);
        raw_error += dr.dot(dr);
      }
    helps.push_back(filtered_error < raw_error);
  }
  return helps;
}

}  // namespace propcam::render
