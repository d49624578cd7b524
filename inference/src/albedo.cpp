#include "propcam/inference/albedo.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <vector>

#include "propcam/inference/poisson.h"
#include "luminance.h"

namespace propcam::inference {
namespace {

constexpr double kLogOffset = 1e-4;  // keeps log finite on black pixels
constexpr double kMaxAlbedo = 0.95;
// Intensity below which chromaticity is noise and is not compared.
constexpr double kMinChromaticityIntensity = 1e-3;

// Grey world (AlbedoOptions::grey_world): each channel scaled so that the
// mean colour is grey at the mean's luminance.
void make_mean_grey(cv::Mat& albedo, StageReport& report) {
  const cv::Scalar mean = cv::mean(albedo);
  const Eigen::Vector3d m(mean[0], mean[1], mean[2]);
  const double level = luminance(m);
  Eigen::Vector3d gains = Eigen::Vector3d::Ones();
  if (level > 0)
    for (int c = 0; c < 3; ++c)
      gains[c] = m[c] > 0 ? std::clamp(level / m[c], 1.0 / kMaxGreyWorldGain, kMaxGreyWorldGain) : kMaxGreyWorldGain;
  albedo = albedo.mul(cv::Scalar(gains[0], gains[1], gains[2]));
  cv::min(cv::max(albedo, 0.0), kMaxAlbedo, albedo);
  report.details["grey_world_gains"] = {gains[0], gains[1], gains[2]};
}

cv::Mat albedo_with_its_cast(const cv::Mat& photo_linear, const AlbedoOptions& options, StageReport& report) {
  if (photo_linear.empty() || photo_linear.type() != CV_32FC3)
    throw std::invalid_argument("estimate_albedo: need a non-empty CV_32FC3 image");
  if (options.method == AlbedoOptions::Method::BlurredShading) {
    const cv::Mat lum = luminance_image(photo_linear);
    const double sigma = std::max(1.0, options.blur_sigma_fraction * std::hypot(lum.cols, lum.rows));
    cv::Mat shading;
    cv::GaussianBlur(lum, shading, cv::Size(0, 0), sigma, sigma, cv::BORDER_REFLECT);
    shading = cv::max(shading, kLogOffset);
    std::vector<cv::Mat> channels;
    cv::split(photo_linear, channels);
    for (auto& c : channels) c = cv::min(cv::max(options.mean_albedo * c / shading, 0.0), kMaxAlbedo);
    cv::Mat albedo;
    cv::merge(channels, albedo);
    report.stage = "albedo";
    report.usable = true;
    report.why = "photo divided by blurred luminance (baseline)";
    return albedo;
  }
  // Solve at a bounded resolution: shading is smooth, and the albedo's detail
  // comes back from the photo itself (albedo = photo / shading).
  cv::Mat work = photo_linear;
  const int max_w = std::max(8, options.max_solve_width);
  if (photo_linear.cols > max_w) {
    const int h = std::max(2, static_cast<int>(std::lround(static_cast<double>(max_w) * photo_linear.rows / photo_linear.cols)));
    cv::resize(photo_linear, work, {max_w, h}, 0, 0, cv::INTER_AREA);
  }
  const int w = work.cols, h = work.rows;
  cv::Mat log_i(h, w, CV_64F), chroma(h, w, CV_64FC3), intensity(h, w, CV_64F);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const cv::Vec3f c = work.at<cv::Vec3f>(y, x);
      const double sum = std::max(0.f, c[0]) + std::max(0.f, c[1]) + std::max(0.f, c[2]);
      intensity.at<double>(y, x) = sum / 3.0;
      log_i.at<double>(y, x) = std::log(sum / 3.0 + kLogOffset);
      chroma.at<cv::Vec3d>(y, x) =
          sum > 0 ? cv::Vec3d(c[0] / sum, c[1] / sum, c[2] / sum) : cv::Vec3d(1.0 / 3, 1.0 / 3, 1.0 / 3);
    }
  cv::Mat gx(h, w, CV_64F, cv::Scalar(0)), gy(h, w, CV_64F, cv::Scalar(0));
  int reflectance_edges = 0;
  auto classify = [&](int y0, int x0, int y1, int x1) {
    const double d = log_i.at<double>(y1, x1) - log_i.at<double>(y0, x0);
    const bool lit = std::min(intensity.at<double>(y0, x0), intensity.at<double>(y1, x1)) > kMinChromaticityIntensity;
    const double dc = lit ? cv::norm(chroma.at<cv::Vec3d>(y1, x1) - chroma.at<cv::Vec3d>(y0, x0)) : 0.0;
    const bool reflectance = dc > options.chromaticity_threshold || std::abs(d) > options.log_intensity_threshold;
    reflectance_edges += reflectance;
    return reflectance ? d : 0.0;
  };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      if (x + 1 < w) gx.at<double>(y, x) = classify(y, x, y, x + 1);
      if (y + 1 < h) gy.at<double>(y, x) = classify(y, x, y + 1, x);
    }
  const cv::Mat log_r = integrate_gradients(gx, gy);
  // Shading (grey) = intensity / reflectance, at the work resolution, then
  // brought to the photo's size; albedo per channel = photo / shading.
  cv::Mat shading(h, w, CV_32F);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      shading.at<float>(y, x) = static_cast<float>(std::exp(log_i.at<double>(y, x) - log_r.at<double>(y, x)));
  if (work.size() != photo_linear.size()) cv::resize(shading, shading, photo_linear.size(), 0, 0, cv::INTER_LINEAR);
  // Scale: the image's mean reflectance is options.mean_albedo.
  cv::Mat raw(photo_linear.size(), CV_32FC3);
  double sum = 0;
  for (int y = 0; y < raw.rows; ++y)
    for (int x = 0; x < raw.cols; ++x) {
      const cv::Vec3f c = photo_linear.at<cv::Vec3f>(y, x);
      const float s = std::max(shading.at<float>(y, x), static_cast<float>(kLogOffset));
      const cv::Vec3f a(std::max(0.f, c[0]) / s, std::max(0.f, c[1]) / s, std::max(0.f, c[2]) / s);
      raw.at<cv::Vec3f>(y, x) = a;
      sum += (a[0] + a[1] + a[2]) / 3.0;
    }
  const double mean = sum / std::max<size_t>(1, raw.total());
  const double scale = mean > 0 ? options.mean_albedo / mean : 0.0;
  cv::Mat albedo = cv::min(cv::max(raw * scale, 0.0), kMaxAlbedo);
  report.stage = "albedo";
  report.usable = true;
  report.why = "Color Retinex, DCT Poisson integration";
  report.iterations = 1;
  report.details = {{"solve_size", {w, h}}, {"reflectance_edges", reflectance_edges},
                    {"chromaticity_threshold", options.chromaticity_threshold},
                    {"log_intensity_threshold", options.log_intensity_threshold}};
  return albedo;
}

}  // namespace

cv::Mat estimate_albedo(const cv::Mat& photo_linear, const AlbedoOptions& options, StageReport& report) {
  const auto start = std::chrono::steady_clock::now();
  cv::Mat albedo = albedo_with_its_cast(photo_linear, options, report);
  // A NaN pixel becomes black paint on every architecture: OpenCV's min/max
  // drop NaN only in x86's SIMD lanes (NEON and scalar tails keep it).
  cv::patchNaNs(albedo, 0.0);
  if (options.grey_world) {
    make_mean_grey(albedo, report);
    report.why += ", mean made grey";
  }
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return albedo;
}

void scale_albedo(cv::Mat& albedo, double scale) {
  if (!std::isfinite(scale) || scale < 0) throw std::invalid_argument("scale_albedo: scale must be finite and >= 0");
  albedo = cv::min(cv::max(albedo * scale, 0.0), kMaxAlbedo);
}

double local_mse(const cv::Mat& estimate, const cv::Mat& truth, int window) {
  if (estimate.size() != truth.size() || estimate.type() != truth.type())
    throw std::invalid_argument("local_mse: images must match");
  const int step = std::max(1, window / 2);
  double error = 0, energy = 0;
  cv::Mat e, t;
  estimate.convertTo(e, CV_64F);
  truth.convertTo(t, CV_64F);
  e = e.reshape(1, e.rows);
  t = t.reshape(1, t.rows);
  const int ch = estimate.channels();
  for (int y = 0; y + window <= estimate.rows; y += step)
    for (int x = 0; x + window <= estimate.cols; x += step) {
      const cv::Rect r(x * ch, y, window * ch, window);
      const cv::Mat ew = e(r), tw = t(r);
      const double ee = ew.dot(ew), et = ew.dot(tw), tt = tw.dot(tw);
      const double alpha = ee > 0 ? et / ee : 0.0;
      error += tt - 2 * alpha * et + alpha * alpha * ee;
      energy += tt;
    }
  return energy > 0 ? error / energy : 0.0;
}

}  // namespace propcam::inference
