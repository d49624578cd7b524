#include "propcam/inference/ibl_distance.h"

#include <cmath>
#include <stdexcept>
#include <vector>

#include "luminance.h"

namespace propcam::inference {
namespace {

constexpr double kPi = 3.14159265358979323846;
// Normals the sphere is "rendered" at: a 32x16 latlong grid is ample for a
// band-limited (degree <= 2) signal.
constexpr int kSphereCols = 32, kSphereRows = 16;
// Below this mean luminance a sphere is black and is not rescaled.
constexpr double kBlackLuminance = 1e-12;

Eigen::Vector3d uv_to_direction(double u, double v) {
  const double phi = u * 2.0 * kPi - kPi, theta = v * kPi, s = std::sin(theta);
  return {s * std::sin(phi), std::cos(theta), -s * std::cos(phi)};
}

Eigen::Matrix<double, 9, 1> sh_basis(const Eigen::Vector3d& d) {
  const double x = d.x(), y = d.y(), z = d.z();
  Eigen::Matrix<double, 9, 1> b;
  b << 0.282095, 0.488603 * y, 0.488603 * z, 0.488603 * x, 1.092548 * x * y, 1.092548 * y * z,
      0.315392 * (3 * z * z - 1), 1.092548 * x * z, 0.546274 * (x * x - y * y);
  return b;
}

double texel_solid_angle(int y, int rows, int cols) {
  return (2.0 * kPi / cols) * (std::cos(kPi * y / rows) - std::cos(kPi * (y + 1) / rows));
}

}  // namespace

ShRadiance project_radiance_sh(const cv::Mat& latlong) {
  if (latlong.empty() || latlong.type() != CV_32FC3)
    throw std::invalid_argument("SH projection needs a non-empty CV_32FC3 latlong");
  ShRadiance sh = ShRadiance::Zero();
  for (int y = 0; y < latlong.rows; ++y) {
    const double w = texel_solid_angle(y, latlong.rows, latlong.cols);
    for (int x = 0; x < latlong.cols; ++x) {
      const cv::Vec3f c = latlong.at<cv::Vec3f>(y, x);
      Eigen::Vector3d radiance;
      for (int k = 0; k < 3; ++k) radiance[k] = std::isfinite(c[k]) && c[k] > 0 ? c[k] : 0.0;
      const auto b = sh_basis(uv_to_direction((x + 0.5) / latlong.cols, (y + 0.5) / latlong.rows));
      sh += w * b * radiance.transpose();
    }
  }
  return sh;
}

Eigen::Vector3d sh_irradiance(const ShRadiance& sh, const Eigen::Vector3d& normal) {
  // Lambertian kernel per band (Ramamoorthi & Hanrahan): pi, 2pi/3, pi/4.
  static const double kBand[9] = {kPi, 2 * kPi / 3, 2 * kPi / 3, 2 * kPi / 3, kPi / 4, kPi / 4, kPi / 4, kPi / 4, kPi / 4};
  const auto b = sh_basis(normal.normalized());
  Eigen::Vector3d e = Eigen::Vector3d::Zero();
  for (int i = 0; i < 9; ++i) e += kBand[i] * b[i] * sh.row(i).transpose();
  return e.cwiseMax(0.0);  // band limiting can ring below zero under a sun
}

double ibl_render_distance(const ShRadiance& a, const ShRadiance& b) {
  return ibl_render_distance(a, Eigen::Matrix3d::Identity(), b, Eigen::Matrix3d::Identity());
}

double ibl_render_distance(const ShRadiance& a, const Eigen::Matrix3d& rotation_a, const ShRadiance& b,
                           const Eigen::Matrix3d& rotation_b) {
  if (!rotation_a.allFinite() || !rotation_b.allFinite())
    throw std::invalid_argument("IBL distance: rotation is not finite");
  std::vector<Eigen::Vector3d> sa, sb;
  std::vector<double> weight;
  double mean_a = 0, mean_b = 0, total = 0;
  for (int y = 0; y < kSphereRows; ++y)
    for (int x = 0; x < kSphereCols; ++x) {
      const Eigen::Vector3d n = uv_to_direction((x + 0.5) / kSphereCols, (y + 0.5) / kSphereRows);
      const double w = texel_solid_angle(y, kSphereRows, kSphereCols);
      sa.push_back(sh_irradiance(a, rotation_a * n) / kPi);
      sb.push_back(sh_irradiance(b, rotation_b * n) / kPi);
      weight.push_back(w);
      mean_a += w * luminance(sa.back());
      mean_b += w * luminance(sb.back());
      total += w;
    }
  mean_a /= total;
  mean_b /= total;
  const double scale_a = mean_a > kBlackLuminance ? 1.0 / mean_a : 0.0;
  const double scale_b = mean_b > kBlackLuminance ? 1.0 / mean_b : 0.0;
  double sum = 0;
  for (size_t i = 0; i < sa.size(); ++i) sum += weight[i] * (scale_a * sa[i] - scale_b * sb[i]).squaredNorm() / 3.0;
  const double d = std::sqrt(sum / total);
  return std::isfinite(d) ? d : 0.0;
}

}  // namespace propcam::inference
