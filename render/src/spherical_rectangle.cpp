#include "spherical_rectangle.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace propcam::render::detail {
namespace {

using Eigen::Vector3d;

// Where 1 - h^2 is this small the row's height goes to the far edge directly.
constexpr double kMinOneMinusH2 = 1e-12;

double angle_between_planes(const Vector3d& a, const Vector3d& b) { return std::acos(std::clamp(-a.dot(b), -1.0, 1.0)); }

}  // namespace

std::optional<SphericalRectangle> SphericalRectangle::seen_from(const Vector3d& from, const Vector3d& corner,
                                                                const Vector3d& edge_u, const Vector3d& edge_v) {
  const double length_u = edge_u.norm(), length_v = edge_v.norm();
  if (!(length_u > 0.0 && length_v > 0.0) || !from.allFinite()) return std::nullopt;
  if (std::abs(edge_u.dot(edge_v)) > kMaxRectangleEdgeCosine * length_u * length_v) return std::nullopt;
  SphericalRectangle r;
  r.origin_ = from;
  r.x_ = edge_u / length_u;
  r.y_ = edge_v / length_v;
  r.z_ = r.x_.cross(r.y_);
  const Vector3d d = corner - from;
  // In the local frame the rectangle lies at z = z0 < 0: the point is on the side z faces.
  r.z0_ = d.dot(r.z_);
  if (!(r.z0_ < 0.0)) return std::nullopt;
  r.x0_ = d.dot(r.x_);
  r.y0_ = d.dot(r.y_);
  r.x1_ = r.x0_ + length_u;
  r.y1_ = r.y0_ + length_v;
  const Vector3d v00(r.x0_, r.y0_, r.z0_), v01(r.x0_, r.y1_, r.z0_), v10(r.x1_, r.y0_, r.z0_), v11(r.x1_, r.y1_, r.z0_);
  // Normals of the four planes through the point and an edge, and the
  // spherical rectangle's inner angles between them.
  const Vector3d n0 = v00.cross(v10).normalized(), n1 = v10.cross(v11).normalized();
  const Vector3d n2 = v11.cross(v01).normalized(), n3 = v01.cross(v00).normalized();
  const double g0 = angle_between_planes(n0, n1), g1 = angle_between_planes(n1, n2);
  const double g2 = angle_between_planes(n2, n3), g3 = angle_between_planes(n3, n0);
  r.b0_ = n0.z();
  r.b1_ = n2.z();
  r.k_ = 2.0 * std::numbers::pi - g2 - g3;
  r.solid_angle_ = g0 + g1 - r.k_;
  if (!(r.solid_angle_ >= kMinSphericalRectangleSolidAngle && r.solid_angle_ <= kMaxSphericalRectangleSolidAngle))
    return std::nullopt;
  return r;
}

Vector3d SphericalRectangle::sample(double u1, double u2) const {
  // The column x(u1) that cuts off the fraction u1 of the solid angle...
  const double au = u1 * solid_angle_ + k_;
  const double fu = (std::cos(au) * b0_ - b1_) / std::sin(au);
  double cu = std::copysign(1.0, fu) / std::sqrt(fu * fu + b0_ * b0_);
  if (!std::isfinite(cu)) cu = std::copysign(1.0, fu);
  cu = std::clamp(cu, -1.0, 1.0);
  double xu = -(cu * z0_) / std::sqrt(std::max(0.0, 1.0 - cu * cu));
  xu = std::isnan(xu) ? 0.5 * (x0_ + x1_) : std::clamp(xu, x0_, x1_);
  // ...then the height along that column, uniform in its solid angle.
  const double dist = std::sqrt(xu * xu + z0_ * z0_);
  const double h0 = y0_ / std::sqrt(dist * dist + y0_ * y0_), h1 = y1_ / std::sqrt(dist * dist + y1_ * y1_);
  const double hv = h0 + u2 * (h1 - h0), one_minus_hv2 = 1.0 - hv * hv;
  const double yv = one_minus_hv2 > kMinOneMinusH2 ? std::clamp(hv * dist / std::sqrt(one_minus_hv2), y0_, y1_) : y1_;
  return origin_ + xu * x_ + yv * y_ + z0_ * z_;
}

}  // namespace propcam::render::detail
