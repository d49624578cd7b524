#include "propcam/render/lights.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>

#include "luminance.h"
#include "area_light_sampler.h"

namespace propcam::render {
namespace {
constexpr float kPi = std::numbers::pi_v<float>;
constexpr double kPiD = std::numbers::pi;
constexpr float kInfinity = std::numeric_limits<float>::infinity();
// Brightest texel an environment keeps, so that its sums stay finite.
constexpr float kMaxEnvironmentTexel = 1e6f;
// A sampled light point seen at a cosine below this (edge-on) contributes
// nothing: its pdf dist^2 / (cos * area) would overflow.
constexpr double kMinLightCosine = 1e-7;
// A point closer to a light than this (m) receives nothing from that sample
// (the inverse-square factor would overflow).
constexpr double kMinLightDistance = 1e-6;
// A spot's half-angle is at most a right angle (Blender's spot_size at most
// 180 degrees): beyond it Cycles' cos(theta) factor would turn negative.
constexpr double kMaxSpotHalfAngle = kPiD / 2.0;

using Eigen::Vector3d;
using Eigen::Vector3f;

bool emits_radiance(const Vector3f& radiance) { return radiance.allFinite() && radiance.maxCoeff() > 0.f; }

// Two unit vectors completing the unit `axis` to an orthonormal basis (Duff et al. 2017).
void orthonormal_basis(const Vector3d& axis, Vector3d& t, Vector3d& bt) {
  const double sign = std::copysign(1.0, axis.z());
  const double a = -1.0 / (sign + axis.z());
  const double b = axis.x() * axis.y() * a;
  t = Vector3d(1.0 + sign * axis.x() * axis.x() * a, sign * b, -sign * axis.x());
  bt = Vector3d(b, sign + axis.y() * axis.y() * a, -axis.y());
}

// Unit vector within `one_minus_cos_max` of the unit axis, uniform over the
// cone's solid angle (cos theta = 1 - u1 * (1 - cos_max), done in 1 - cos so
// that tiny cones such as the sun's keep their precision).
Vector3d sample_cone(const Vector3d& axis, double one_minus_cos_max, double u1, double u2) {
  const double one_minus_cos = u1 * one_minus_cos_max;
  const double cos_theta = 1.0 - one_minus_cos;
  const double sin_theta = std::sqrt(std::max(0.0, one_minus_cos * (2.0 - one_minus_cos)));
  const double phi = 2.0 * kPiD * u2;
  Vector3d t, bt;
  orthonormal_basis(axis, t, bt);
  return (sin_theta * std::cos(phi) * t + sin_theta * std::sin(phi) * bt + cos_theta * axis).normalized();
}

// The unit square onto the unit disc, preserving area and keeping
// neighbouring samples neighbours (Shirley and Chiu's concentric map), so
// stratified numbers stay stratified on a disc light.
Eigen::Vector2d concentric_disc(double u1, double u2) {
  const double a = 2.0 * u1 - 1.0, b = 2.0 * u2 - 1.0;
  if (a == 0.0 && b == 0.0) return Eigen::Vector2d::Zero();
  const bool wide = std::abs(a) > std::abs(b);
  const double r = wide ? a : b;
  const double phi = wide ? 0.25 * kPiD * (b / a) : 0.5 * kPiD - 0.25 * kPiD * (a / b);
  return {r * std::cos(phi), r * std::sin(phi)};
}

// Cycles' smoothstep: 3x^2 - 2x^3 on [0, 1].
double smoothstep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

// 1 - cos of the half-angle of a sphere of radius^2 r2 seen from distance^2 d2 > r2.
double sphere_one_minus_cos(double r2, double d2) {
  const double sin2 = r2 / d2;
  return sin2 / (1.0 + std::sqrt(std::max(0.0, 1.0 - sin2)));
}

double sun_radius(double angular_radius) {
  if (!std::isfinite(angular_radius)) return kMinSunAngularRadius;
  return std::clamp(angular_radius, kMinSunAngularRadius, kMaxSunAngularRadius);
}

using detail::luminance;

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
  if (!scale_.allFinite()) scale_.setZero();
  scale_ = scale_.cwiseMax(0.f);
  image_ = latlong.clone();
  // Negative and non-finite texels (NaN, +-Inf) become 0; the rest are capped.
  for (int y = 0; y < image_.rows; ++y) {
    auto* row = image_.ptr<float>(y);
    for (int i = 0; i < image_.cols * 3; ++i)
      row[i] = std::isfinite(row[i]) ? std::clamp(row[i], 0.f, kMaxEnvironmentTexel) : 0.f;
  }
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
  if (!direction.allFinite() || image_.empty()) return Vector3f::Zero();
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
  if (!direction.allFinite() || image_.empty()) return 0.f;
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

bool AreaLight::emits() const {
  return corner.allFinite() && edge_u.allFinite() && edge_v.allFinite() && area() > kMinAreaLightArea &&
         emits_radiance(radiance);
}

LightSample AreaLight::sample(const Vector3f& from, float u1, float u2) const {
  return detail::AreaLightSampler(*this).sample(from, u1, u2);
}

bool AreaLight::intersect(const Vector3f& origin, const Vector3f& direction, float& t, float& pdf) const {
  return detail::AreaLightSampler(*this).intersect(origin, direction, t, pdf);
}

namespace detail {

AreaLightSampler::AreaLightSampler(const AreaLight& light)
    : corner_(light.corner.cast<double>()),
      edge_u_(light.edge_u.cast<double>()),
      edge_v_(light.edge_v.cast<double>()),
      area_normal_(edge_u_.cross(edge_v_)),
      area_(area_normal_.norm()),
      uu_(edge_u_.dot(edge_u_)),
      uv_(edge_u_.dot(edge_v_)),
      vv_(edge_v_.dot(edge_v_)),
      gram_det_(uu_ * vv_ - uv_ * uv_),
      radiance_(light.radiance),
      emits_(light.emits()) {
  if (emits_) rectangle_ = RectangleFrame::of(corner_, edge_u_, edge_v_);
}

std::optional<SphericalRectangle> AreaLightSampler::seen_from(const Vector3d& from) const {
  if (!rectangle_) return std::nullopt;
  return SphericalRectangle::seen_from(from, *rectangle_);
}

LightSample AreaLightSampler::sample(const Vector3f& from, float u1, float u2) const {
  LightSample out;
  if (!emits_) return out;
  // A rectangle is sampled by solid angle where the parametrisation holds,
  // a parallelogram (or a rectangle seen from too far or too flat) by area.
  const Vector3d from_d = from.cast<double>();
  const auto rectangle = seen_from(from_d);
  const Vector3d point = rectangle ? rectangle->sample(u1, u2) : Vector3d(corner_ + u1 * edge_u_ + u2 * edge_v_);
  Vector3d to = point - from_d;
  const double dist2 = to.squaredNorm();
  if (!(dist2 > kMinLightDistance * kMinLightDistance)) return out;
  const double dist = std::sqrt(dist2);
  to /= dist;
  const double cos_light = -to.dot(area_normal_) / area_;
  if (!(cos_light > kMinLightCosine)) return out;  // behind or edge-on
  out.direction = to.cast<float>();
  out.distance = static_cast<float>(dist);
  out.radiance = radiance_;
  out.pdf = static_cast<float>(rectangle ? 1.0 / rectangle->solid_angle() : dist2 / (cos_light * area_));
  return out;
}

bool AreaLightSampler::intersect(const Vector3f& origin, const Vector3f& direction, float& t, float& pdf) const {
  if (!emits_) return false;
  const Vector3d o = origin.cast<double>(), w = direction.cast<double>().normalized();
  const double cos_light = -w.dot(area_normal_) / area_;
  if (!(cos_light > kMinLightCosine)) return false;  // parallel, or arriving at the back
  const double distance = (corner_ - o).dot(area_normal_) / w.dot(area_normal_);
  if (!(distance > kMinLightDistance)) return false;
  // Parallelogram coordinates of the hit: solve [eu ev] (s, t) = q in the plane.
  const Vector3d q = o + distance * w - corner_;
  const double s = (vv_ * q.dot(edge_u_) - uv_ * q.dot(edge_v_)) / gram_det_;
  const double r = (uu_ * q.dot(edge_v_) - uv_ * q.dot(edge_u_)) / gram_det_;
  if (s < 0.0 || s > 1.0 || r < 0.0 || r > 1.0) return false;
  t = static_cast<float>(distance);
  const auto rectangle = seen_from(o);
  pdf = static_cast<float>(rectangle ? 1.0 / rectangle->solid_angle() : distance * distance / (cos_light * area_));
  return std::isfinite(pdf);
}

}  // namespace detail

bool SpotCone::valid() const {
  return direction.allFinite() && direction.norm() > 0.f && std::isfinite(half_angle) && std::isfinite(blend);
}

double SpotCone::attenuation_at_cos(double cos_theta) const {
  if (!valid() || !std::isfinite(cos_theta)) return 0.0;
  const double cos_half = std::cos(std::clamp(half_angle, 0.0, kMaxSpotHalfAngle));
  const double c = std::min(cos_theta, 1.0);
  if (!(c > cos_half)) return 0.0;  // outside the cone (a zero cone holds nothing)
  // The blend is a band of cosines just inside the edge, as Cycles measures it.
  const double band = (1.0 - cos_half) * std::clamp(blend, 0.0, 1.0);
  const double t = c - cos_half;
  return t < band ? c * smoothstep(t / band) : c;
}

double SpotCone::attenuation(const Vector3d& w) const {
  if (!valid() || !w.allFinite()) return 0.0;
  const Vector3d axis = direction.cast<double>();
  const double norms = axis.norm() * w.norm();
  if (!(norms > 0.0)) return 0.0;
  return attenuation_at_cos(axis.dot(w) / norms);
}

bool SphereLight::emits() const {
  return center.allFinite() && std::isfinite(radius) && radius > kMinSphereLightRadius && emits_radiance(radiance) &&
         (!spot || spot->valid());
}

Vector3f SphereLight::radiance_toward(const Vector3f& point) const {
  if (!spot) return radiance;
  const double a = spot->attenuation(point.cast<double>() - center.cast<double>());
  return (radiance.cast<double>() * a).cast<float>();
}

LightSample SphereLight::sample(const Vector3f& from, float u1, float u2) const {
  LightSample out;
  if (!emits()) return out;
  const Vector3d oc = center.cast<double>() - from.cast<double>();
  const double d2 = oc.squaredNorm(), r2 = static_cast<double>(radius) * radius;
  if (!(d2 > r2)) return out;  // inside (or on) the sphere: it emits outward only
  const Vector3f arriving = radiance_toward(from);
  if (!emits_radiance(arriving)) return out;  // outside its spot cone
  const double d = std::sqrt(d2);
  const double one_minus_cos = sphere_one_minus_cos(r2, d2);
  const Vector3d w = sample_cone(oc / d, one_minus_cos, u1, u2);
  // First intersection along w; the perpendicular distance comes from a cross
  // product (no cancellation for tiny spheres), and is clamped at the cone edge.
  const double b = w.dot(oc);
  const double perp2 = oc.cross(w).squaredNorm();
  const double distance = b - std::sqrt(std::max(0.0, r2 - perp2));
  if (!(distance > 0.0)) return out;
  out.direction = w.cast<float>();
  out.distance = static_cast<float>(distance);
  out.radiance = arriving;
  out.pdf = static_cast<float>(1.0 / (2.0 * kPiD * one_minus_cos));
  if (!std::isfinite(out.pdf)) out = LightSample{};
  return out;
}

bool SphereLight::intersect(const Vector3f& origin, const Vector3f& direction, float& t, float& pdf) const {
  if (!emits()) return false;
  const Vector3d oc = center.cast<double>() - origin.cast<double>();
  const Vector3d w = direction.cast<double>().normalized();
  const double d2 = oc.squaredNorm(), r2 = static_cast<double>(radius) * radius;
  if (!(d2 > r2)) return false;
  const double b = w.dot(oc);
  if (!(b > 0.0)) return false;
  const double perp2 = oc.cross(w).squaredNorm();
  if (perp2 > r2) return false;
  t = static_cast<float>(b - std::sqrt(r2 - perp2));
  pdf = static_cast<float>(1.0 / (2.0 * kPiD * sphere_one_minus_cos(r2, d2)));
  return t > 0.f && std::isfinite(pdf);
}

double DiscLight::area() const { return kPiD * static_cast<double>(radius) * radius; }

bool DiscLight::emits() const {
  return centre.allFinite() && normal.allFinite() && normal.norm() > 0.f && std::isfinite(radius) &&
         radius > kMinDiscLightRadius && emits_radiance(radiance);
}

LightSample DiscLight::sample(const Vector3f& from, float u1, float u2) const {
  LightSample out;
  if (!emits()) return out;
  const Vector3d n = normal.cast<double>().normalized();
  Vector3d t, b;
  orthonormal_basis(n, t, b);
  const Eigen::Vector2d q = static_cast<double>(radius) * concentric_disc(u1, u2);
  Vector3d to = centre.cast<double>() + q.x() * t + q.y() * b - from.cast<double>();
  const double dist2 = to.squaredNorm();
  if (!(dist2 > kMinLightDistance * kMinLightDistance)) return out;
  const double dist = std::sqrt(dist2);
  to /= dist;
  const double cos_light = -to.dot(n);
  if (!(cos_light > kMinLightCosine)) return out;  // behind or edge-on
  out.direction = to.cast<float>();
  out.distance = static_cast<float>(dist);
  out.radiance = radiance;
  out.pdf = static_cast<float>(dist2 / (cos_light * area()));
  if (!std::isfinite(out.pdf)) out = LightSample{};
  return out;
}

bool DiscLight::intersect(const Vector3f& origin, const Vector3f& direction, float& t, float& pdf) const {
  if (!emits()) return false;
  const Vector3d o = origin.cast<double>(), w = direction.cast<double>().normalized();
  const Vector3d n = normal.cast<double>().normalized();
  const double cos_light = -w.dot(n);
  if (!(cos_light > kMinLightCosine)) return false;  // parallel, or arriving at the back
  const double distance = (centre.cast<double>() - o).dot(n) / w.dot(n);
  if (!(distance > kMinLightDistance)) return false;
  const Vector3d q = o + distance * w - centre.cast<double>();
  const double r = radius;
  if (q.squaredNorm() > r * r) return false;
  t = static_cast<float>(distance);
  pdf = static_cast<float>(distance * distance / (cos_light * area()));
  return std::isfinite(pdf);
}

bool PointLight::emits() const {
  return position.allFinite() && emits_radiance(intensity) && (!spot || spot->valid());
}

LightSample PointLight::sample(const Vector3f& from, float /*u1*/, float /*u2*/) const {
  LightSample out;
  if (!emits()) return out;
  Vector3d to = position.cast<double>() - from.cast<double>();
  const double dist2 = to.squaredNorm();
  // At the light itself there is no direction and I/d^2 has no limit.
  if (!(dist2 > kMinLightDistance * kMinLightDistance)) return out;
  const double dist = std::sqrt(dist2);
  to /= dist;
  const double scale = (spot ? spot->attenuation(-to) : 1.0) / dist2;
  const Vector3d arriving = intensity.cast<double>() * scale;
  if (!(arriving.maxCoeff() > 0.0) || !arriving.allFinite()) return out;
  out.direction = to.cast<float>();
  out.distance = static_cast<float>(dist);
  out.radiance = arriving.cast<float>();
  if (!out.radiance.allFinite()) return LightSample{};
  out.pdf = 1.f;
  out.delta = true;
  return out;
}

bool SunLight::emits() const {
  return direction.allFinite() && direction.norm() > 0.f && emits_radiance(irradiance);
}

Vector3f SunLight::radiance() const {
  if (!emits()) return Vector3f::Zero();
  // The cone's projected solid angle about its axis is pi sin^2(radius).
  const double s = std::sin(sun_radius(angular_radius));
  return (irradiance.cast<double>() / (kPiD * s * s)).cast<float>();
}

LightSample SunLight::sample(float u1, float u2) const {
  LightSample out;
  if (!emits()) return out;
  const double half = 0.5 * sun_radius(angular_radius);
  const double one_minus_cos = 2.0 * std::sin(half) * std::sin(half);
  out.direction = sample_cone(direction.cast<double>().normalized(), one_minus_cos, u1, u2).cast<float>();
  out.distance = kInfinity;
  out.radiance = radiance();
  out.pdf = static_cast<float>(1.0 / (2.0 * kPiD * one_minus_cos));
  return out;
}

float SunLight::pdf(const Vector3f& dir) const {
  if (!emits() || !dir.allFinite()) return 0.f;
  const double radius = sun_radius(angular_radius);
  const Vector3d axis = direction.cast<double>().normalized();
  const Vector3d w = dir.cast<double>();
  const double len2 = w.squaredNorm();
  if (!(len2 > 0.0) || !(axis.dot(w) > 0.0)) return 0.f;
  // Inside the cone by the sine of the angle (a cross product stays precise for tiny cones).
  const double sin_max = std::sin(radius);
  if (axis.cross(w).squaredNorm() / len2 > sin_max * sin_max) return 0.f;
  const double half = 0.5 * radius;
  return static_cast<float>(1.0 / (2.0 * kPiD * 2.0 * std::sin(half) * std::sin(half)));
}

LightRig LightRig::only(int index) const {
  LightRig rig;
  if (index < 0 || index >= count()) throw std::out_of_range("light index out of range");
  if (index < first_sphere()) rig.area_lights.push_back(area_lights[index]);
  else if (index < first_sun()) rig.sphere_lights.push_back(sphere_lights[index - first_sphere()]);
  else if (index < first_disc()) rig.suns.push_back(suns[index - first_sun()]);
  else if (index < first_point()) rig.disc_lights.push_back(disc_lights[index - first_disc()]);
  else if (index < environment_index()) rig.point_lights.push_back(point_lights[index - first_point()]);
  else rig.environment = environment;
  rig.portals = portals;
  return rig;
}

bool Portal::valid() const {
  return corner.allFinite() && edge_u.allFinite() && edge_v.allFinite() &&
         edge_u.cross(edge_v).norm() >= kMinAreaLightArea;
}

bool Portal::crossed_by(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction) const {
  if (!valid()) return false;
  // In double: a window metres away, crossed at a grazing angle.
  const Eigen::Vector3d o = origin.cast<double>(), d = direction.cast<double>(), c = corner.cast<double>();
  const Eigen::Vector3d u = edge_u.cast<double>(), v = edge_v.cast<double>();
  const Eigen::Vector3d n = u.cross(v);
  const double facing = n.dot(d);
  if (!(std::abs(facing) > 1e-12 * n.norm() * d.norm())) return false;  // parallel, or not finite
  const double t = n.dot(c - o) / facing;
  if (!(t > 0.0)) return false;
  const Eigen::Vector3d hit = o + t * d - c;
  // Coordinates along the (possibly skewed) edges, by the Gram system.
  const double uu = u.dot(u), uv = u.dot(v), vv = v.dot(v), hu = hit.dot(u), hv = hit.dot(v);
  const double det = uu * vv - uv * uv;
  const double s = (hu * vv - hv * uv) / det, r = (hv * uu - hu * uv) / det;
  return s >= 0.0 && s <= 1.0 && r >= 0.0 && r <= 1.0;
}

bool LightRig::arrives_from_outside(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction,
                                    bool through_portals) const {
  if (!through_portals) return true;
  for (const Portal& portal : portals)
    if (portal.crossed_by(origin, direction)) return true;
  return false;
}

}  // namespace propcam::render
