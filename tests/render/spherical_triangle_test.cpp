#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <optional>
#include <random>

#include "spherical_triangle.h"

namespace propcam::render {
namespace {

using detail::SphericalTriangle;
using Eigen::Vector3d;

// Where the ray from the origin along d meets the plane of a, b, c, in
// barycentric coordinates (b, c weights); nullopt when it misses the plane.
std::optional<Eigen::Vector2d> barycentric_hit(const Vector3d& d, const Vector3d& a, const Vector3d& b,
                                               const Vector3d& c) {
  const Vector3d e1 = b - a, e2 = c - a, p = d.cross(e2);
  const double det = e1.dot(p);
  if (det == 0.0) return std::nullopt;
  const Vector3d s = -a;
  const double u = s.dot(p) / det, v = d.dot(s.cross(e1)) / det;
  const double t = e2.dot(s.cross(e1)) / det;
  if (!(t > 0.0)) return std::nullopt;
  return Eigen::Vector2d(u, v);
}

TEST(SphericalTriangle, OctantSubtendsAnEighthOfTheSphere) {
  const auto t = SphericalTriangle::seen_from(Vector3d::Zero(), Vector3d::UnitX(), Vector3d::UnitY(), Vector3d::UnitZ());
  ASSERT_TRUE(t);
  EXPECT_NEAR(t->solid_angle(), std::numbers::pi / 2, 1e-12);
  // Far away it is the area over the squared distance, from either side and winding.
  const Vector3d a(-0.5, -0.5, 100.0), b(0.5, -0.5, 100.0), c(0.0, 0.5, 100.0);
  const auto far = SphericalTriangle::seen_from(Vector3d::Zero(), a, c, b);
  ASSERT_TRUE(far);
  EXPECT_NEAR(far->solid_angle(), 0.5 / 1e4, 1e-8);
  const auto behind = SphericalTriangle::seen_from(Vector3d(0, 0, 200), a, b, c);
  ASSERT_TRUE(behind);
  EXPECT_NEAR(behind->solid_angle(), far->solid_angle(), 1e-12);
}

// Every sample meets the triangle, and the samples fall into any part of it
// in proportion to that part's solid angle (uniform density), for triangles
// from 1 cm to 100 m seen from 1 cm to 30 m.
TEST(SphericalTriangle, SamplesAreUniformOverTheTriangle) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const auto random_vector = [&] { return Vector3d(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5).normalized(); };
  int tested = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const double size = std::pow(10.0, -2.0 + 4.0 * unit(rng)), distance = std::pow(10.0, -2.0 + 3.5 * unit(rng));
    const Vector3d centre = distance * random_vector();
    const Vector3d a = centre + size * random_vector(), b = centre + size * random_vector(),
                   c = centre + size * random_vector();
    const auto t = SphericalTriangle::seen_from(Vector3d::Zero(), a, b, c);
    // The part a, b, m with m on the edge b -> c.
    const double split = 0.2 + 0.6 * unit(rng);
    const Vector3d m = b + split * (c - b);
    const auto part = SphericalTriangle::seen_from(Vector3d::Zero(), a, b, m);
    if (!t || !part) continue;
    ++tested;
    const double expected = part->solid_angle() / t->solid_angle();
    constexpr int kSamples = 2000;
    int inside_part = 0;
    for (int i = 0; i < kSamples; ++i) {
      const Vector3d d = t->sample(unit(rng), unit(rng));
      ASSERT_NEAR(d.norm(), 1.0, 1e-9);
      const auto hit = barycentric_hit(d, a, b, c);
      ASSERT_TRUE(hit) << "trial " << trial;
      const double tolerance = 1e-6;
      ASSERT_GE(hit->x(), -tolerance);
      ASSERT_GE(hit->y(), -tolerance);
      ASSERT_LE(hit->x() + hit->y(), 1.0 + tolerance);
      // In barycentric terms the part is where the weight of c is at most split times that of b and c together.
      if (hit->y() <= split * (hit->x() + hit->y())) ++inside_part;
    }
    const double fraction = static_cast<double>(inside_part) / kSamples;
    const double sigma = std::sqrt(expected * (1.0 - expected) / kSamples);
    EXPECT_NEAR(fraction, expected, 5.0 * sigma + 1e-3) << "trial " << trial << " size " << size << " distance " << distance;
  }
  EXPECT_GT(tested, 150);
}

TEST(SphericalTriangle, DegenerateViewsAreRefused) {
  const Vector3d a(0, 0, 1), b(1, 0, 1), c(0, 1, 1);
  EXPECT_FALSE(SphericalTriangle::seen_from(Vector3d(0.2, 0.2, 1.0), a, b, c));  // in its plane
  EXPECT_FALSE(SphericalTriangle::seen_from(a, a, b, c));                        // on a corner
  EXPECT_FALSE(SphericalTriangle::seen_from(Vector3d(0, 0, std::nan("")), a, b, c));
  EXPECT_FALSE(SphericalTriangle::seen_from(Vector3d::Zero(), a, a, c));                      // no area
  // Too small to parametrise: refused, the caller samples it by area.
  EXPECT_FALSE(SphericalTriangle::seen_from(Vector3d::Zero(), 1e4 * a, 1e4 * a + Vector3d(1, 0, 0), 1e4 * a + Vector3d(0, 1, 0)));
  // Extreme numbers stay on the triangle.
  const auto t = SphericalTriangle::seen_from(Vector3d::Zero(), a, b, c);
  ASSERT_TRUE(t);
  for (const double u1 : {0.0, 1e-12, 0.5, 1.0 - 1e-12, 1.0})
    for (const double u2 : {0.0, 1e-12, 0.5, 1.0 - 1e-12, 1.0}) {
      const Vector3d d = t->sample(u1, u2);
      ASSERT_TRUE(d.allFinite());
      const auto hit = barycentric_hit(d, a, b, c);
      ASSERT_TRUE(hit);
      EXPECT_GE(hit->x(), -1e-6);
      EXPECT_GE(hit->y(), -1e-6);
      EXPECT_LE(hit->x() + hit->y(), 1.0 + 1e-6);
    }
}

}  // namespace
}  // namespace propcam::render
