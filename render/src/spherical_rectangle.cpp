#include "spherical_rectangle.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace propcam::render::detail {
namespace {

using Eigen::Vector3d;

// Where 1 - h^2 is this small the row's height goes to the far edge directly.
constexpr double kMinOneMinusH2 = 1e-12;

// An angle held as its cosine and sine: adding angles is multiplying these,
// so the four inner angles are summed with two products and one atan2 instead
// of four acos (and without the cancellation of 2 pi against their sum).
struct UnitAngle {
  double c, s;
  UnitAngle operator*(const UnitAngle& o) const { return {c * o.c - s * o.s, s * o.c + c * o.s}; }
  // The angle in [0, 2 pi).
  double radians() const {
    const double a = std::atan2(s, c);
    return a < 0.0 ? a + 2.0 * std::numbers::pi : a;
  }
};

// The inner angle between two edge planes from the z components of their
// normals: in the rectangle's frame adjacent normals meet with -cos = nz_a nz_b.
UnitAngle inner_angle(double nz_a, double nz_b) {
  const double c = std::clamp(-nz_a * nz_b, -1.0, 1.0);
  return {c, std::sqrt(std::max(0.0, 1.0 - c * c))};
}

}  // namespace

std::optional<RectangleFrame> RectangleFrame::of(const Vector3d& corner, const Vector3d& edge_u, const Vector3d& edge_v) {
  RectangleFrame f;
  f.length_u = edge_u.norm();
  f.length_v = edge_v.norm();
  if (!(f.length_u > 0.0 && f.length_v > 0.0) || !std::isfinite(f.length_u) || !std::isfinite(f.length_v) ||
      !corner.allFinite())
    return std::nullopt;
  if (std::abs(edge_u.dot(edge_v)) > kMaxRectangleEdgeCosine * f.length_u * f.length_v) return std::nullopt;
  f.corner = corner;
  f.x = edge_u / f.length_u;
  f.y = edge_v / f.length_v;
  f.z = f.x.cross(f.y);
  return f;
}

std::optional<SphericalRectangle> SphericalRectangle::seen_from(const Vector3d& from, const RectangleFrame& rectangle) {
  if (!from.allFinite()) return std::nullopt;
  SphericalRectangle r;
  r.origin_ = from;
  r.x_ = rectangle.x;
  r.y_ = rectangle.y;
  r.z_ = rectangle.z;
  const Vector3d d = rectangle.corner - from;
  // In the local frame the rectangle lies at z = z0 < 0: the point is on the side z faces.
  r.z0_ = d.dot(r.z_);
  if (!(r.z0_ < 0.0)) return std::nullopt;
  r.x0_ = d.dot(r.x_);
  r.y0_ = d.dot(r.y_);
  r.x1_ = r.x0_ + rectangle.length_u;
  r.y1_ = r.y0_ + rectangle.length_v;
  // The planes through the point and each edge (y = y0, x = x1, y = y1,
  // x = x0, in turn) have normals (0, z0, -y0), (-z0, 0, x1), (0, -z0, y1)
  // and (z0, 0, -x0), normalised; only their z components are needed.
  const double z0_2 = r.z0_ * r.z0_;
  const double nz0 = -r.y0_ / std::sqrt(z0_2 + r.y0_ * r.y0_), nz1 = r.x1_ / std::sqrt(z0_2 + r.x1_ * r.x1_);
  const double nz2 = r.y1_ / std::sqrt(z0_2 + r.y1_ * r.y1_), nz3 = -r.x0_ / std::sqrt(z0_2 + r.x0_ * r.x0_);
  const UnitAngle g01 = inner_angle(nz0, nz1) * inner_angle(nz1, nz2);
  const UnitAngle g23 = inner_angle(nz2, nz3) * inner_angle(nz3, nz0);
  r.b0_ = nz0;
  r.b1_ = nz2;
  r.k_ = 2.0 * std::numbers::pi - g23.radians();
  // The four angles' sum less 2 pi, read from their product (in (0, 2 pi) for
  // any point in front of the rectangle).
  r.solid_angle_ = (g01 * g23).radians();
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
