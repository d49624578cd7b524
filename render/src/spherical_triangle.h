// A triangle as seen from a point, sampled uniformly by solid angle (Arvo
// 1995, "Stratified Sampling of Spherical Triangles"); internal to render/.
// A large emissive triangle close to the shading point subtends far more
// solid angle at its near corner than area sampling gives it; this gives
// every direction toward the triangle the same density.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>

namespace propcam::render::detail {

// Below this solid angle (sr) the spherical angles lose their digits against
// pi; a triangle that small is as well sampled by area.
constexpr double kMinSphericalTriangleSolidAngle = 1e-6;
// Above it the point lies nearly in the triangle's plane (the solid angle
// tends to 2 pi) and the inversion is ill-conditioned.
constexpr double kMaxSphericalTriangleSolidAngle = 6.2;

class SphericalTriangle {
 public:
  // The triangle a, b, c (either winding, seen from either side) as seen
  // from `from`; empty when it cannot be sampled this way (non-finite input,
  // `from` in its plane, or a solid angle outside the bounds above).
  static std::optional<SphericalTriangle> seen_from(const Eigen::Vector3d& from, const Eigen::Vector3d& a,
                                                    const Eigen::Vector3d& b, const Eigen::Vector3d& c);

  double solid_angle() const { return solid_angle_; }
  // The unit direction given by (u1, u2) in [0,1)^2; directions are uniform
  // over the solid angle and every one of them meets the triangle.
  Eigen::Vector3d sample(double u1, double u2) const;

 private:
  Eigen::Vector3d a_, b_, c_;  // unit directions toward the corners
  double alpha_ = 0, cos_alpha_ = 0, sin_alpha_ = 0, cos_c_ = 0;  // angle at a, cosine of the arc ab
  double area_ = 0;        // alpha + beta + gamma - pi, the parametrisation's own total
  double solid_angle_ = 0;  // the same area, from Van Oosterom and Strackee (accurate when small)
};

}  // namespace propcam::render::detail
