// A rectangle as seen from a point, sampled uniformly by solid angle (Ureña,
// Fajardo and King 2013, "An Area-Preserving Parametrization for Spherical
// Rectangles"); internal to render/. Area sampling wastes most samples of a
// large light close by (its near part subtends far more solid angle than its
// far part); this gives every direction toward the rectangle the same density.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>

namespace propcam::render::detail {

// Below this solid angle (sr) the parametrisation's angle sums lose their
// digits; area sampling is as good there (the light is small and far).
constexpr double kMinSphericalRectangleSolidAngle = 1e-5;
// Above it the point lies nearly in the rectangle's plane (the solid angle
// tends to 2 pi) and the inversion is ill-conditioned.
constexpr double kMaxSphericalRectangleSolidAngle = 6.2;
// Edges whose cosine exceeds this are not a rectangle (a parallelogram is
// sampled by area instead).
constexpr double kMaxRectangleEdgeCosine = 1e-4;

// The rectangle corner + s*edge_u + t*edge_v in its own orthonormal frame
// (x along edge_u, y along edge_v, z = x cross y): what does not depend on the
// point it is seen from, derived once per light.
struct RectangleFrame {
  Eigen::Vector3d corner, x, y, z;
  double length_u = 0, length_v = 0;
  // Empty when the edges are not those of a rectangle (zero, non-finite or
  // skewed beyond kMaxRectangleEdgeCosine).
  static std::optional<RectangleFrame> of(const Eigen::Vector3d& corner, const Eigen::Vector3d& edge_u,
                                          const Eigen::Vector3d& edge_v);
};

class SphericalRectangle {
 public:
  // The rectangle seen from `from`; empty when it cannot be sampled this way
  // (`from` in or behind its plane on the side opposite to z, or a solid
  // angle outside the bounds above).
  static std::optional<SphericalRectangle> seen_from(const Eigen::Vector3d& from, const RectangleFrame& rectangle);

  double solid_angle() const { return solid_angle_; }
  // The point of the rectangle in the direction given by (u1, u2) in [0,1)^2;
  // directions are uniform over the solid angle.
  Eigen::Vector3d sample(double u1, double u2) const;

 private:
  Eigen::Vector3d origin_, x_, y_, z_;
  double x0_ = 0, x1_ = 0, y0_ = 0, y1_ = 0, z0_ = 0;
  double b0_ = 0, b1_ = 0, k_ = 0, solid_angle_ = 0;
};

}  // namespace propcam::render::detail
