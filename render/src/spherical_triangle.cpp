#include "spherical_triangle.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace propcam::render::detail {
namespace {

using Eigen::Vector3d;

// `v` less its component along the unit `axis`, normalised; `fallback` when
// nothing is left (v along the axis).
Vector3d orthogonal_part(const Vector3d& v, const Vector3d& axis, const Vector3d& fallback) {
  const Vector3d w = v - v.dot(axis) * axis;
  const double n = w.norm();
  return n > 0.0 && std::isfinite(n) ? Vector3d(w / n) : fallback;
}

}  // namespace

std::optional<SphericalTriangle> SphericalTriangle::seen_from(const Vector3d& from, const Vector3d& a,
                                                              const Vector3d& b, const Vector3d& c) {
  if (!from.allFinite() || !a.allFinite() || !b.allFinite() || !c.allFinite()) return std::nullopt;
  SphericalTriangle t;
  t.a_ = (a - from).normalized();
  t.b_ = (b - from).normalized();
  t.c_ = (c - from).normalized();
  if (!t.a_.allFinite() || !t.b_.allFinite() || !t.c_.allFinite()) return std::nullopt;  // `from` on a corner
  const double ab = t.a_.dot(t.b_), bc = t.b_.dot(t.c_), ca = t.c_.dot(t.a_);
  const double volume = std::abs(t.a_.dot(t.b_.cross(t.c_)));
  if (!(volume > 0.0)) return std::nullopt;  // in the triangle's plane
  t.solid_angle_ = 2.0 * std::atan2(volume, 1.0 + ab + bc + ca);
  if (!(t.solid_angle_ >= kMinSphericalTriangleSolidAngle && t.solid_angle_ <= kMaxSphericalTriangleSolidAngle))
    return std::nullopt;
  // The angle at a corner is the angle between the planes through it and each
  // neighbour: |(a x b) x (a x c)| = |a . (b x c)|, (a x b).(a x c) = b.c - (a.b)(a.c).
  t.alpha_ = std::atan2(volume, bc - ab * ca);
  const double beta = std::atan2(volume, ca - ab * bc);
  const double gamma = std::atan2(volume, ab - ca * bc);
  t.area_ = t.alpha_ + beta + gamma - std::numbers::pi;
  if (!(t.area_ > 0.0)) return std::nullopt;
  t.cos_alpha_ = std::cos(t.alpha_);
  t.sin_alpha_ = std::sin(t.alpha_);
  t.cos_c_ = ab;
  return t;
}

Vector3d SphericalTriangle::sample(double u1, double u2) const {
  // The sub-triangle a, b, c' of area u1 * area: where c' lies on the arc a -> c...
  const double sub_area = u1 * area_;
  const double s = std::sin(sub_area - alpha_), t = std::cos(sub_area - alpha_);
  const double u = t - cos_alpha_, v = s + sin_alpha_ * cos_c_;
  const double denominator = (v * s + u * t) * sin_alpha_;
  double q = denominator != 0.0 ? ((v * t - u * s) * cos_alpha_ - v) / denominator : 1.0;
  q = std::isfinite(q) ? std::clamp(q, -1.0, 1.0) : 1.0;
  const Vector3d c_prime = q * a_ + std::sqrt(std::max(0.0, 1.0 - q * q)) * orthogonal_part(c_, a_, c_);
  // ...then the direction on the arc b -> c', uniform in the sub-triangle's added area.
  const double z = std::clamp(1.0 - u2 * (1.0 - c_prime.dot(b_)), -1.0, 1.0);
  return z * b_ + std::sqrt(std::max(0.0, 1.0 - z * z)) * orthogonal_part(c_prime, b_, c_prime);
}

}  // namespace propcam::render::detail
