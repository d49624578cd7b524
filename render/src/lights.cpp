#include "propcam/render/lights.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace propcam::render {
namespace {
constexpr float kPi = std::numbers::pi_v<float>;

float luminance(const cv::Vec3f& c) { return 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2]; }

// Index of the first cdf entry greater than u, clamped to a valid bin.
int find_bin(const float* cdf, int n, float u) {
  const float* it = std::upper_bound(cdf, cdf + n + 1, u);
  return std::clamp(static_cast<int>(it - cdf) - 1, 0, n - 1);
}
}  // namespace

Eigen::Vector2f EnvironmentLight::direction_to_uv(const Eigen::Vector3f& d) {
  const float phi = std::atan2(d.x(), -d.z());  // (-pi, pi]
  const float theta = std::acos(std::clamp(d.y(), -1.f, 1.f));
  float u = (phi + kPi) / (2.f * kPi);
  if (u >= 1.f) u -= 1.f;
  return {u, theta / kPi};
}

Eigen::Vector3f EnvironmentLight::uv_to_direction(float u, float v) {
  const float phi = u * 2.f * kPi - kPi;
  const float theta = v * kPi;
  const float s = std::sin(theta);
  return {s * std::sin(phi), std::cos(theta), -s * std::cos(phi)};
}

EnvironmentLight::EnvironmentLight(const cv::Mat& latlong, Eigen::Vector3f scale) : scale_(scale) {
  if (latlong.empty() || latlong.type() != CV_32FC3)
    throw std::invalid_argument("environment map must be a non-empty CV_32FC3 image");
  image_ = latlong.clone();
  cv::patchNaNs(image_, 0.0);
  cv::max(image_, 0.0, image_);
  cv::min(image_, 1e6, image_);  // keep sums finite even for absurd inputs
  const int rows = image_.rows, cols = image_.cols;
  conditional_cdf_.assign(static_cast<size_t>(rows) * (cols + 1), 0.f);
  row_weight_.assign(rows, 0.f);
  marginal_cdf_.assign(rows + 1, 0.f);
  for (int y = 0; y < rows; ++y) {
    const float sin_theta = std::sin((y + 0.5f) / rows * kPi);
    float* cdf = &conditional_cdf_[static_cast<size_t>(y) * (cols + 1)];
    const cv::Vec3f* row = image_.ptr<cv::Vec3f>(y);
    double acc = 0.0;
    for (int x = 0; x < cols; ++x) {
      // A small floor keeps every direction sampleable (the estimator stays unbiased).
      acc += (luminance(row[x]) + 1e-6f) * sin_theta;
      cdf[x + 1] = static_cast<float>(acc);
    }
    row_weight_[y] = static_cast<float>(acc);
    for (int x = 1; x <= cols; ++x) cdf[x] /= static_cast<float>(acc);
    marginal_cdf_[y + 1] = marginal_cdf_[y] + row_weight_[y];
  }
  total_weight_ = marginal_cdf_[rows];
  for (auto& c : marginal_cdf_) c /= total_weight_;
}

Eigen::Vector3f EnvironmentLight::radiance(const Eigen::Vector3f& direction) const {
  const Eigen::Vector2f uv = direction_to_uv(direction);
  const int x = std::clamp(static_cast<int>(uv.x() * image_.cols), 0, image_.cols - 1);
  const int y = std::clamp(static_cast<int>(uv.y() * image_.rows), 0, image_.rows - 1);
  const cv::Vec3f c = image_.at<cv::Vec3f>(y, x);
  return {c[0] * scale_.x(), c[1] * scale_.y(), c[2] * scale_.z()};
}

Eigen::Vector3f EnvironmentLight::sample(float u1, float u2, float& pdf_out) const {
  const int rows = image_.rows, cols = image_.cols;
  const int y = find_bin(marginal_cdf_.data(), rows, u1);
  const float* cdf = &conditional_cdf_[static_cast<size_t>(y) * (cols + 1)];
  const int x = find_bin(cdf, cols, u2);
  // Continuous position inside the chosen texel.
  const float dy = (u1 - marginal_cdf_[y]) / std::max(marginal_cdf_[y + 1] - marginal_cdf_[y], 1e-12f);
  const float dx = (u2 - cdf[x]) / std::max(cdf[x + 1] - cdf[x], 1e-12f);
  const float u = (x + std::clamp(dx, 0.f, 1.f)) / cols;
  const float v = (y + std::clamp(dy, 0.f, 1.f)) / rows;
  const Eigen::Vector3f d = uv_to_direction(u, v);
  pdf_out = pdf(d);
  return d;
}

float EnvironmentLight::pdf(const Eigen::Vector3f& direction) const {
  const int rows = image_.rows, cols = image_.cols;
  const Eigen::Vector2f uv = direction_to_uv(direction);
  const int x = std::clamp(static_cast<int>(uv.x() * cols), 0, cols - 1);
  const int y = std::clamp(static_cast<int>(uv.y() * rows), 0, rows - 1);
  const float sin_theta = std::sin((y + 0.5f) / rows * kPi);
  if (sin_theta <= 0.f) return 0.f;
  const float* cdf = &conditional_cdf_[static_cast<size_t>(y) * (cols + 1)];
  const float pdf_uv = (marginal_cdf_[y + 1] - marginal_cdf_[y]) * rows * (cdf[x + 1] - cdf[x]) * cols;
  return pdf_uv / (2.f * kPi * kPi * sin_theta);
}

LightRig LightRig::only(int index) const {
  LightRig rig;
  const int n_area = static_cast<int>(area_lights.size());
  if (index < n_area) rig.area_lights.push_back(area_lights[index]);
  else if (index == n_area && environment) rig.environment = environment;
  else throw std::out_of_range("light index out of range");
  return rig;
}

}  // namespace propcam::render
