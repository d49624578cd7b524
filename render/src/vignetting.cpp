#include "propcam/render/vignetting.h"

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "luminance.h"

namespace propcam::render {
namespace {

// A flat field smaller than this says nothing about a lens's fall-off.
constexpr int kMinFlatFieldSidePx = 32;
// The fit runs on the frame reduced to this width: the fall-off is smooth,
// and averaging pixels takes the sensor's noise out.
constexpr int kFitWidthPx = 128;
// Linear values: below kBlack a pixel is noise, at or above kClipped it
// has lost the fall-off.
constexpr float kBlack = 0.01f;
constexpr float kClipped = 0.98f;
// A flat field this dark is mostly noise and rounding.
constexpr double kMinFlatFieldMedian = 0.03;
// The radius is sampled this finely to check the gain over [0, 1].
constexpr int kGainChecks = 64;

double normalised_radius(double x, double y, cv::Size size) {
  const double half_diagonal = 0.5 * std::hypot(size.width, size.height);
  if (!(half_diagonal > 0)) return 0.0;
  return std::hypot(x + 0.5 - 0.5 * size.width, y + 0.5 - 0.5 * size.height) / half_diagonal;
}

}  // namespace

double Vignetting::at_radius(double r) const {
  const double s = std::clamp(r, 0.0, 1.0);
  const double s2 = s * s;
  return std::exp(r2 * s2 + r4 * s2 * s2);
}

double Vignetting::at_pixel(double x, double y, cv::Size size) const {
  return at_radius(normalised_radius(x, y, size));
}

std::string vignetting_problem(const Vignetting& v) {
  if (!std::isfinite(v.r2) || !std::isfinite(v.r4)) return "coefficients must be finite";
  if (std::abs(v.r2) > kMaxVignettingCoefficient || std::abs(v.r4) > kMaxVignettingCoefficient) {
    char text[64];
    std::snprintf(text, sizeof text, "coefficients must be within +-%.1f", kMaxVignettingCoefficient);
    return text;
  }
  for (int i = 0; i <= kGainChecks; ++i) {
    const double gain = v.at_radius(static_cast<double>(i) / kGainChecks);
    if (gain < kMinVignetteGain || gain > kMaxVignetteGain) {
      char text[160];
      std::snprintf(text, sizeof text, "gain %.3f at radius %.2f is outside [%.2f, %.2f]", gain,
                    static_cast<double>(i) / kGainChecks, kMinVignetteGain, kMaxVignetteGain);
      return text;
    }
  }
  return "";
}

VignettingFit fit_vignetting(const std::vector<cv::Mat>& flat_fields_linear) {
  if (flat_fields_linear.empty()) throw std::invalid_argument("fit_vignetting: no flat-field frames");
  const cv::Size size = flat_fields_linear.front().size();
  cv::Mat sum(size, CV_32FC3, cv::Scalar::all(0));
  for (const cv::Mat& frame : flat_fields_linear) {
    if (frame.type() != CV_32FC3 || frame.empty())
      throw std::invalid_argument("fit_vignetting: a flat-field frame must be linear RGB (CV_32FC3)");
    if (frame.size() != size)
      throw std::invalid_argument("fit_vignetting: the flat-field frames differ in size (they must share the camera's framing)");
    if (!cv::checkRange(frame)) throw std::invalid_argument("fit_vignetting: a flat-field frame has non-finite values");
    sum += frame;
  }
  if (std::min(size.width, size.height) < kMinFlatFieldSidePx)
    throw std::invalid_argument("fit_vignetting: the flat field is smaller than " + std::to_string(kMinFlatFieldSidePx) +
                                " px on a side");
  const cv::Mat mean = sum / static_cast<double>(flat_fields_linear.size());

  // Luminance, and where it can be read: no channel black or clipped.
  cv::Mat luminance(size, CV_32F), usable(size, CV_32F);
  int usable_pixels = 0;
  for (int r = 0; r < size.height; ++r) {
    const auto* px = mean.ptr<cv::Vec3f>(r);
    auto* y = luminance.ptr<float>(r);
    auto* u = usable.ptr<float>(r);
    for (int c = 0; c < size.width; ++c) {
      y[c] = detail::luminance(px[c]);
      const bool ok = std::min({px[c][0], px[c][1], px[c][2]}) > kBlack &&
                      std::max({px[c][0], px[c][1], px[c][2]}) < kClipped;
      u[c] = ok ? 1.0f : 0.0f;
      usable_pixels += ok;
    }
  }
  const double usable_share = static_cast<double>(usable_pixels) / size.area();
  if (usable_share < kMinFlatFieldUsableShare) {
    char text[200];
    std::snprintf(text, sizeof text,
                  "fit_vignetting: only %.0f%% of the flat field is neither black nor clipped (at least %.0f%%): "
                  "change the exposure",
                  100.0 * usable_share, 100.0 * kMinFlatFieldUsableShare);
    throw std::invalid_argument(text);
  }
  std::vector<float> values(luminance.begin<float>(), luminance.end<float>());
  std::nth_element(values.begin(), values.begin() + static_cast<long>(values.size() / 2), values.end());
  if (values[values.size() / 2] < kMinFlatFieldMedian) {
    char text[160];
    std::snprintf(text, sizeof text,
                  "fit_vignetting: the flat field is too dark to read (median luminance below %.2f): expose it brighter",
                  kMinFlatFieldMedian);
    throw std::invalid_argument(text);
  }

  // Reduced, a reduced pixel counts only when all it averages was usable.
  const double scale = std::min(1.0, static_cast<double>(kFitWidthPx) / size.width);
  const cv::Size reduced_size(std::max(1, static_cast<int>(std::lround(size.width * scale))),
                              std::max(1, static_cast<int>(std::lround(size.height * scale))));
  cv::Mat reduced, reduced_usable;
  cv::resize(luminance, reduced, reduced_size, 0, 0, cv::INTER_AREA);
  cv::resize(usable, reduced_usable, reduced_size, 0, 0, cv::INTER_AREA);

  // log Y = c + gx x + gy y + r2 r^2 + r4 r^4, x and y over the half-diagonal.
  const double half_diagonal = 0.5 * std::hypot(reduced_size.width, reduced_size.height);
  std::vector<Eigen::Matrix<double, 5, 1>> rows;
  std::vector<double> targets;
  for (int r = 0; r < reduced_size.height; ++r)
    for (int c = 0; c < reduced_size.width; ++c) {
      if (reduced_usable.at<float>(r, c) < 0.999f) continue;
      const double x = (c + 0.5 - 0.5 * reduced_size.width) / half_diagonal;
      const double y = (r + 0.5 - 0.5 * reduced_size.height) / half_diagonal;
      const double s2 = x * x + y * y;
      rows.push_back((Eigen::Matrix<double, 5, 1>() << 1.0, x, y, s2, s2 * s2).finished());
      targets.push_back(std::log(static_cast<double>(reduced.at<float>(r, c))));
    }
  if (rows.size() < 16) throw std::invalid_argument("fit_vignetting: too few usable pixels in the flat field");
  Eigen::MatrixXd a(rows.size(), 5);
  Eigen::VectorXd b(rows.size());
  for (size_t i = 0; i < rows.size(); ++i) {
    a.row(static_cast<Eigen::Index>(i)) = rows[i].transpose();
    b(static_cast<Eigen::Index>(i)) = targets[i];
  }
  const Eigen::VectorXd p = a.colPivHouseholderQr().solve(b);
  const double residual_rms = std::sqrt((a * p - b).squaredNorm() / static_cast<double>(rows.size()));
  if (!p.allFinite() || !std::isfinite(residual_rms))
    throw std::invalid_argument("fit_vignetting: the fit did not converge to finite values");

  VignettingFit fit;
  fit.vignetting.r2 = p(3);
  fit.vignetting.r4 = p(4);
  fit.residual_rms = residual_rms;
  fit.gradient = std::hypot(p(1), p(2));
  fit.pixels = static_cast<int>(rows.size());
  if (residual_rms > kMaxFlatFieldResidual) {
    char text[240];
    std::snprintf(text, sizeof text,
                  "fit_vignetting: not a flat field: %.1f%% of log luminance is left after the vignette and a linear "
                  "gradient (at most %.0f%%): the surface or its light is not even",
                  100.0 * residual_rms, 100.0 * kMaxFlatFieldResidual);
    throw std::invalid_argument(text);
  }
  if (const std::string problem = vignetting_problem(fit.vignetting); !problem.empty())
    throw std::invalid_argument("fit_vignetting: the fitted vignetting is no lens's: " + problem);
  return fit;
}

namespace {

// Each pixel times V, or divided by it (CV_32FC3).
cv::Mat scaled_by_gain(const cv::Mat& linear, const Vignetting& vignetting, bool divide, const char* caller) {
  if (linear.type() != CV_32FC3) throw std::invalid_argument(std::string(caller) + ": need a CV_32FC3 linear image");
  cv::Mat out(linear.size(), CV_32FC3);
  for (int r = 0; r < out.rows; ++r) {
    const auto* in = linear.ptr<cv::Vec3f>(r);
    auto* px = out.ptr<cv::Vec3f>(r);
    for (int c = 0; c < out.cols; ++c) {
      const double gain = vignetting.at_pixel(c, r, out.size());
      px[c] = in[c] * static_cast<float>(divide ? 1.0 / gain : gain);
    }
  }
  return out;
}

}  // namespace

cv::Mat vignette_image(const cv::Mat& linear, const Vignetting& vignetting) {
  return vignetting.known() ? scaled_by_gain(linear, vignetting, false, "vignette_image") : linear.clone();
}

cv::Mat devignette(const cv::Mat& photo_linear, const Vignetting& vignetting) {
  return vignetting.known() ? scaled_by_gain(photo_linear, vignetting, true, "devignette") : photo_linear;
}

void vignette_prop(const cv::Mat& photo_linear, cv::Mat& composite_linear, const cv::Mat& coverage,
                   const Vignetting& vignetting) {
  if (photo_linear.type() != CV_32FC3 || composite_linear.type() != CV_32FC3 || coverage.type() != CV_32F ||
      photo_linear.size() != composite_linear.size() || coverage.size() != composite_linear.size())
    throw std::invalid_argument("vignette_prop: need CV_32FC3 photo and composite and a CV_32F coverage of one size");
  cv::Mat& out = composite_linear;
  const cv::Size size = out.size();
  for (int r = 0; r < size.height; ++r) {
    const float* m = coverage.ptr<float>(r);
    const auto* photo = photo_linear.ptr<cv::Vec3f>(r);
    auto* px = out.ptr<cv::Vec3f>(r);
    for (int c = 0; c < size.width; ++c) {
      if (!(m[c] > 0) && px[c] == photo[c]) continue;  // neither covered nor changed: exactly the photo
      const float uncovered = 1.0f - std::clamp(m[c], 0.0f, 1.0f);
      const float gain_less_one = static_cast<float>(vignetting.at_pixel(c, r, size) - 1.0);
      // The prop's layer: what the photo's uncovered share does not explain.
      for (int ch = 0; ch < 3; ++ch) px[c][ch] += gain_less_one * (px[c][ch] - uncovered * photo[c][ch]);
    }
  }
}

}  // namespace propcam::render
