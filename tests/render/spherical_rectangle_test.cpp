#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <optional>
#include <random>

#include "spherical_rectangle.h"

namespace propcam::render {
namespace {

using detail::SphericalRectangle;
using Eigen::Vector3d;

// Solid angle of the triangle a, b, c seen from the origin (Van Oosterom and
// Strackee 1983): an independent formula, accurate for tiny triangles too.
double triangle_solid_angle(const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  const double la = a.norm(), lb = b.norm(), lc = c.norm();
  const double numerator = std::abs(a.dot(b.cross(c)));
  const double denominator = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
  double angle = 2.0 * std::atan2(numerator, denominator);
  return angle < 0.0 ? angle + 4.0 * std::acos(-1.0) : angle;
}

struct Rectangle {
  Vector3d corner, edge_u, edge_v;
  Vector3d at(double s, double t) const { return corner + s * edge_u + t * edge_v; }
  // Seen from the origin.
  std::optional<SphericalRectangle> seen() const {
    const auto frame = detail::RectangleFrame::of(corner, edge_u, edge_v);
    return frame ? SphericalRectangle::seen_from(Vector3d::Zero(), *frame) : std::nullopt;
  }
};

// A rectangle of random size, place and turn, and a point in front of it.
Rectangle random_rectangle(std::mt19937& rng, double distance) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Eigen::Quaterniond turn = Eigen::Quaterniond::UnitRandom();
  Rectangle r;
  r.edge_u = turn * Vector3d(0.1 + 2.0 * unit(rng), 0.0, 0.0);
  r.edge_v = turn * Vector3d(0.0, 0.1 + 2.0 * unit(rng), 0.0);
  // The rectangle faces +z in its own frame; the point sits on that side.
  const Vector3d offset(4.0 * unit(rng) - 2.0, 4.0 * unit(rng) - 2.0, distance);
  r.corner = -(turn * offset);
  return r;
}

// The solid angle the parametrisation integrates over agrees with the
// triangle formula, from close by (large angles) to far away (1e-5 sr).
TEST(SphericalRectangle, SolidAngleMatchesTwoTriangles) {
  std::mt19937 rng(11);
  int checked = 0;
  for (const double distance : {0.05, 0.3, 1.0, 5.0, 40.0, 300.0}) {
    for (int i = 0; i < 200; ++i) {
      const Rectangle r = random_rectangle(rng, distance);
      const auto seen = r.seen();
      const double expected = triangle_solid_angle(r.at(0, 0), r.at(1, 0), r.at(1, 1)) +
                              triangle_solid_angle(r.at(0, 0), r.at(1, 1), r.at(0, 1));
      if (!seen) {
        // Refused only outside the bounds where the parametrisation holds.
        EXPECT_TRUE(expected < detail::kMinSphericalRectangleSolidAngle * 1.001 ||
                    expected > detail::kMaxSphericalRectangleSolidAngle * 0.999)
            << expected;
        continue;
      }
      EXPECT_NEAR(seen->solid_angle(), expected, 1e-9 + 1e-8 * expected) << "distance " << distance;
      ++checked;
    }
  }
  EXPECT_GT(checked, 1000);
}

// u1 = 0 and u1 -> 1 give the rectangle's two side edges, u2 its near and far
// edges, and every sample lies on the rectangle.
TEST(SphericalRectangle, SamplesCoverTheRectangleEdgeToEdge) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int i = 0; i < 100; ++i) {
    const Rectangle r = random_rectangle(rng, 0.2 + 3.0 * unit(rng));
    const auto seen = r.seen();
    ASSERT_TRUE(seen);
    const auto coordinates = [&](const Vector3d& p) {
      const Vector3d q = p - r.corner;
      return Eigen::Vector2d(q.dot(r.edge_u) / r.edge_u.squaredNorm(), q.dot(r.edge_v) / r.edge_v.squaredNorm());
    };
    constexpr double kEdgeTolerance = 1e-6;
    EXPECT_NEAR(coordinates(seen->sample(0.0, 0.5)).x(), 0.0, kEdgeTolerance);
    EXPECT_NEAR(coordinates(seen->sample(1.0 - 1e-12, 0.5)).x(), 1.0, kEdgeTolerance);
    EXPECT_NEAR(coordinates(seen->sample(0.5, 0.0)).y(), 0.0, kEdgeTolerance);
    EXPECT_NEAR(coordinates(seen->sample(0.5, 1.0)).y(), 1.0, kEdgeTolerance);
    for (int k = 0; k < 20; ++k) {
      const Vector3d p = seen->sample(unit(rng), unit(rng));
      const Eigen::Vector2d st = coordinates(p);
      EXPECT_GE(st.x(), -kEdgeTolerance);
      EXPECT_LE(st.x(), 1.0 + kEdgeTolerance);
      EXPECT_GE(st.y(), -kEdgeTolerance);
      EXPECT_LE(st.y(), 1.0 + kEdgeTolerance);
      EXPECT_NEAR((p - r.corner).dot(r.edge_u.cross(r.edge_v).normalized()), 0.0, 1e-9);
    }
  }
}

}  // namespace
}  // namespace propcam::render
