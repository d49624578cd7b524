#include "propcam/inference/sun_choice.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "luminance.h"

namespace propcam::inference {
namespace {

// Below this the sky render sees nothing there (an occluded corner): no ratio.
constexpr double kMinSkyRender = 1e-6;
// Albedos under this are black paint or a clipped estimate: no irradiance from them.
constexpr double kMinAlbedo = 0.02;
constexpr double kMinLuminance = 1e-4;  // keeps the log finite on black pixels
// A side whose variance is below this share of its energy is constant.
constexpr double kRelativeVariance = 1e-12;

// Two passes, so that a constant side is exactly uncorrelated (0), not
// rounding noise.
double correlation(const std::vector<double>& x, const std::vector<double>& y) {
  const size_t n = x.size();
  if (n < 2) return 0.0;
  double mx = 0, my = 0;
  for (size_t i = 0; i < n; ++i) mx += x[i], my += y[i];
  mx /= static_cast<double>(n), my /= static_cast<double>(n);
  double vx = 0, vy = 0, cxy = 0, sxx = 0, syy = 0;
  for (size_t i = 0; i < n; ++i) {
    const double dx = x[i] - mx, dy = y[i] - my;
    vx += dx * dx, vy += dy * dy, cxy += dx * dy, sxx += x[i] * x[i], syy += y[i] * y[i];
  }
  const bool varies = vx > kRelativeVariance * sxx && vy > kRelativeVariance * syy && vx > 0 && vy > 0;
  return varies ? std::clamp(cxy / std::sqrt(vx * vy), -1.0, 1.0) : 0.0;
}

}  // namespace

SunChoice choose_sun(const std::vector<cv::Mat>& candidates, const cv::Mat& sky, const cv::Mat& albedo,
                     const cv::Mat& photo, const std::vector<cv::Point>& pixels, const SunChoiceOptions& options) {
  SunChoice out;
  if (candidates.empty()) return out;
  out.sunlit_share.assign(candidates.size(), 0.0);
  out.agreement.assign(candidates.size(), 0.0);
  const cv::Size size = photo.size();
  const auto usable = [&](const cv::Mat& m) { return m.size() == size && m.type() == CV_32FC3; };
  if (!usable(sky) || !usable(albedo) || !usable(photo)) {
    out.chosen = 0;
    return out;
  }
  // The sky's irradiance (over pi) per pixel: its render over the albedo it
  // was rendered with, both blurred alike.
  cv::Mat sky_lum = luminance_image(sky), albedo_lum = luminance_image(albedo), sky_blur, albedo_blur;
  const double sigma = std::max(0.0, options.sky_irradiance_blur_px);
  if (sigma > 0) {
    cv::GaussianBlur(sky_lum, sky_blur, {0, 0}, sigma);
    cv::GaussianBlur(albedo_lum, albedo_blur, {0, 0}, sigma);
  } else {
    sky_blur = sky_lum, albedo_blur = albedo_lum;
  }
  std::vector<cv::Point> seen;  // pixels the sky render reaches
  std::vector<uint8_t> must;    // per seen pixel: brighter than the sky can make it
  std::vector<double> log_photo;
  for (const cv::Point& p : pixels) {
    if (p.x < 0 || p.y < 0 || p.x >= size.width || p.y >= size.height) continue;
    const double s = sky_lum.at<float>(p);
    if (!(s > kMinSkyRender)) continue;
    const double lum = luminance(photo.at<cv::Vec3f>(p));
    if (!std::isfinite(lum)) continue;
    const double irradiance = sky_blur.at<float>(p) / std::max(kMinAlbedo, static_cast<double>(albedo_blur.at<float>(p)));
    seen.push_back(p);
    const bool brighter = std::isfinite(irradiance) && lum > options.max_albedo * irradiance;
    must.push_back(brighter);
    out.must_be_sunlit += brighter;
    log_photo.push_back(std::log(std::max(kMinLuminance, lum)));
  }
  std::vector<double> relative(seen.size());
  for (size_t c = 0; c < candidates.size(); ++c) {
    if (!usable(candidates[c])) continue;
    for (size_t i = 0; i < seen.size(); ++i) {
      const double r = luminance(candidates[c].at<cv::Vec3f>(seen[i])) / sky_lum.at<float>(seen[i]);
      relative[i] = std::isfinite(r) ? std::max(0.0, r) : 0.0;
    }
    out.agreement[c] = correlation(relative, log_photo);
    if (out.must_be_sunlit == 0 || relative.empty()) continue;
    // Its peak: the 95th percentile of where it lights at all (a low sun may
    // light a few percent of the frame).
    std::vector<double> sorted;
    for (double r : relative)
      if (r > 0) sorted.push_back(r);
    if (sorted.empty()) continue;
    const size_t k95 = static_cast<size_t>(0.95 * static_cast<double>(sorted.size() - 1));
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(k95), sorted.end());
    const double lit_level = options.lit_share_of_peak * sorted[k95];
    if (!(lit_level > 0)) continue;
    int lit = 0;
    for (size_t i = 0; i < seen.size(); ++i) lit += must[i] && relative[i] > lit_level;
    out.sunlit_share[c] = static_cast<double>(lit) / out.must_be_sunlit;
  }
  const double best_share = *std::max_element(out.sunlit_share.begin(), out.sunlit_share.end());
  double best_agreement = -std::numeric_limits<double>::infinity();
  for (size_t c = 0; c < candidates.size(); ++c) {
    if (out.sunlit_share[c] < options.keep_share_of_best * best_share) continue;
    if (out.agreement[c] > best_agreement) best_agreement = out.agreement[c], out.chosen = static_cast<int>(c);
  }
  if (out.chosen < 0) out.chosen = 0;
  return out;
}

}  // namespace propcam::inference
