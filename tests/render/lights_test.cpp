// Light sources in isolation: analytic irradiance from their own samples
// (sphere, sun, rectangle, point, spot, disc), sample/intersect pdf
// agreement, degenerate lights, environment texel clamping and the rig's
// light order.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "propcam/render/lights.h"
#include "sampling.h"

namespace propcam::render {
namespace {

using detail::Rng;
using Eigen::Vector3f;

constexpr double kPi = std::numbers::pi;
constexpr int kIrradianceSamples = 20000;
// Irradiance estimates from light samples are within this relative error
// (cone sampling of a sphere or the sun has almost no variance).
constexpr double kIrradianceTolerance = 5e-3;
// pdf from sample() and from intersect()/pdf() for the same direction (relative, float round-off).
constexpr double kPdfAgreement = 1e-3;

// Irradiance at `point` with unit `normal` from a light's samples.
template <typename SampleFn>
double irradiance(const Vector3f& normal, SampleFn&& sample, uint64_t seed) {
  Rng rng(seed, 1);
  double sum = 0.0;
  for (int i = 0; i < kIrradianceSamples; ++i) {
    const float u1 = rng.uniform(), u2 = rng.uniform();
    const LightSample s = sample(u1, u2);
    if (!(s.pdf > 0.f)) continue;
    sum += s.radiance.x() * std::max(0.f, s.direction.dot(normal)) / s.pdf;
  }
  return sum / kIrradianceSamples;
}

TEST(Lights, SphereLightIrradianceIsPiLTimesRadiusOverDistanceSquared) {
  SphereLight light;
  light.center = {0.f, 2.f, 0.f};
  light.radius = 0.5f;
  light.radiance = Vector3f::Constant(3.f);
  const Vector3f p = Vector3f::Zero();
  const double expected = kPi * 3.0 * std::pow(0.5 / 2.0, 2);
  const auto sample = [&](float u1, float u2) { return light.sample(p, u1, u2); };
  EXPECT_NEAR(irradiance(Vector3f::UnitY(), sample, 1), expected, expected * kIrradianceTolerance);
  // A receiver tilted by 30 degrees (the cone, 14.5 degrees wide, stays above its horizon).
  const Vector3f tilted(std::sin(kPi / 6), std::cos(kPi / 6), 0.f);
  EXPECT_NEAR(irradiance(tilted, sample, 2), expected * std::cos(kPi / 6), expected * kIrradianceTolerance);
}

TEST(Lights, SunIrradianceIsIntensityTimesCosine) {
  for (double theta_deg : {0.0, 30.0, 80.0}) {
    SunLight sun;
    const double t = theta_deg * kPi / 180.0;
    sun.direction = Vector3f(static_cast<float>(std::sin(t)), static_cast<float>(std::cos(t)), 0.f);
    sun.irradiance = Vector3f::Constant(5.f);
    const auto sample = [&](float u1, float u2) { return sun.sample(u1, u2); };
    const double expected = 5.0 * std::cos(t);
    EXPECT_NEAR(irradiance(Vector3f::UnitY(), sample, 3), expected, expected * kIrradianceTolerance) << theta_deg;
  }
}

TEST(Lights, SampledDirectionsHitTheLightWithTheSamePdf) {
  AreaLight area;  // a slanted parallelogram facing roughly -Y
  area.corner = {-0.3f, 2.f, -0.2f};
  area.edge_u = {0.6f, 0.1f, 0.f};
  area.edge_v = {0.2f, 0.f, 0.5f};
  area.radiance = Vector3f::Ones();
  ASSERT_LT(area.normal().y(), 0.f);
  SphereLight sphere;
  sphere.center = {1.f, 1.5f, -0.5f};
  sphere.radius = 0.2f;
  SunLight sun;
  sun.direction = Vector3f(0.3f, 1.f, 0.2f).normalized();
  const Vector3f p(0.1f, 0.f, 0.05f);
  Rng rng(4, 4);
  for (int i = 0; i < 2000; ++i) {
    const float u1 = rng.uniform(), u2 = rng.uniform();
    float t = 0.f, pdf = 0.f;
    const LightSample a = area.sample(p, u1, u2);
    ASSERT_GT(a.pdf, 0.f);
    ASSERT_TRUE(area.intersect(p, a.direction, t, pdf));
    EXPECT_NEAR(t, a.distance, 1e-4f);
    EXPECT_NEAR(pdf, a.pdf, kPdfAgreement * a.pdf);
    const LightSample s = sphere.sample(p, u1, u2);
    ASSERT_GT(s.pdf, 0.f);
    ASSERT_TRUE(sphere.intersect(p, s.direction, t, pdf));
    EXPECT_NEAR(t, s.distance, 1e-3f);
    EXPECT_NEAR(pdf, s.pdf, kPdfAgreement * s.pdf);
    const LightSample d = sun.sample(u1, u2);
    EXPECT_NEAR(sun.pdf(d.direction), d.pdf, kPdfAgreement * d.pdf);
    EXPECT_TRUE(std::isinf(d.distance));
  }
  float t = 0.f, pdf = 0.f;
  EXPECT_FALSE(area.intersect(p, Vector3f(0.f, -1.f, 0.f), t, pdf));      // away from it
  EXPECT_FALSE(area.intersect({0.f, 3.f, 0.f}, -Vector3f::UnitY(), t, pdf));  // at its back
  EXPECT_EQ(sun.pdf(-sun.direction), 0.f);
}

// A rectangle is sampled uniformly by solid angle: its pdf is 1 / solid angle,
// the solid angle of a w x h rectangle seen at distance d from its centre's
// axis is 4 asin(w h / sqrt((w^2 + 4 d^2)(h^2 + 4 d^2))), the sampled points
// lie on it, and irradiance under it matches the analytic value with far less
// spread than area sampling for a large light close by.
TEST(Lights, RectanglesAreSampledBySolidAngle) {
  AreaLight panel;  // 2 m x 1 m, 0.5 m above the origin, facing down, turned 30 degrees about its normal
  const float turn = static_cast<float>(kPi / 6);
  const Vector3f u(std::cos(turn), 0.f, std::sin(turn)), v(-std::sin(turn), 0.f, std::cos(turn));
  panel.edge_u = 1.f * u;
  panel.edge_v = 2.f * v;
  panel.corner = Vector3f(0.f, 0.5f, 0.f) - 0.5f * (panel.edge_u + panel.edge_v);
  panel.radiance = Vector3f::Constant(2.f);
  ASSERT_LT(panel.normal().y(), 0.f);
  const double w = 2.0, h = 1.0, d = 0.5;
  const double solid_angle = 4.0 * std::asin(w * h / std::sqrt((w * w + 4 * d * d) * (h * h + 4 * d * d)));
  const Vector3f p = Vector3f::Zero();
  Rng rng(9, 9);
  double area_sum = 0.0, area_sum2 = 0.0, solid_sum = 0.0, solid_sum2 = 0.0;
  AreaLight skewed = panel;  // the same light as a parallelogram a hair off square is sampled by area
  skewed.edge_v += 0.01f * skewed.edge_u;
  for (int i = 0; i < kIrradianceSamples; ++i) {
    const float u1 = rng.uniform(), u2 = rng.uniform();
    const LightSample s = panel.sample(p, u1, u2);
    ASSERT_GT(s.pdf, 0.f);
    EXPECT_NEAR(s.pdf, 1.0 / solid_angle, 1e-4 / solid_angle);
    // The sampled point lies on the panel's plane, within it.
    const Vector3f q = p + s.distance * s.direction - panel.corner;
    EXPECT_NEAR(q.dot(panel.normal()), 0.f, 1e-4f);
    float t = 0.f, pdf = 0.f;
    ASSERT_TRUE(panel.intersect(p, s.direction, t, pdf));
    EXPECT_NEAR(pdf, s.pdf, kPdfAgreement * s.pdf);
    const double e = s.radiance.x() * std::max(0.f, s.direction.y()) / s.pdf;
    solid_sum += e, solid_sum2 += e * e;
    const LightSample a = skewed.sample(p, u1, u2);
    ASSERT_GT(a.pdf, 0.f);
    const double ea = a.radiance.x() * std::max(0.f, a.direction.y()) / a.pdf;
    area_sum += ea, area_sum2 += ea * ea;
  }
  const double n = kIrradianceSamples;
  const double solid_mean = solid_sum / n, area_mean = area_sum / n;
  const double solid_var = solid_sum2 / n - solid_mean * solid_mean, area_var = area_sum2 / n - area_mean * area_mean;
  // Irradiance of a rectangle from a point on its axis (the sum of four
  // corner patches: E = L sum x/sqrt(x^2+d^2) atan(y/sqrt(x^2+d^2)) + ...).
  const auto corner_patch = [&](double a, double b) {
    const double ra = std::sqrt(a * a + d * d), rb = std::sqrt(b * b + d * d);
    return 0.5 * (a / ra * std::atan(b / ra) + b / rb * std::atan(a / rb));
  };
  const double expected = 2.0 * 4.0 * corner_patch(w / 2, h / 2);
  EXPECT_NEAR(solid_mean, expected, expected * 0.01);
  EXPECT_NEAR(area_mean, expected, expected * 0.03);
  EXPECT_LT(solid_var, 0.5 * area_var);
}

// Seen from nearly in its plane, from far away or from behind, a rectangle
// falls back to area sampling (or gives nothing); never NaN.
TEST(Lights, RectangleSamplingEdgeCasesStayFinite) {
  AreaLight panel;
  panel.corner = {-0.5f, 1.f, -0.5f};
  panel.edge_u = {1.f, 0.f, 0.f};
  panel.edge_v = {0.f, 0.f, 1.f};
  panel.radiance = Vector3f::Ones();
  ASSERT_LT(panel.normal().y(), 0.f);
  const std::vector<Vector3f> points = {{0.f, 0.f, 0.f},        {0.f, 1.f - 1e-6f, 0.f}, {3.f, 1.f - 1e-3f, 0.f},
                                        {0.f, -1e5f, 0.f},      {0.f, 1.f + 1e-6f, 0.f}, {0.f, 2.f, 0.f},
                                        {0.5f, 0.999f, 0.5f},   {1e6f, 0.f, 1e6f}};
  Rng rng(5, 5);
  for (const Vector3f& p : points)
    for (int i = 0; i < 256; ++i) {
      const float u1 = i == 0 ? 0.f : rng.uniform(), u2 = i == 1 ? 0.f : rng.uniform();
      const LightSample s = panel.sample(p, u1, u2);
      ASSERT_TRUE(std::isfinite(s.pdf) && s.pdf >= 0.f) << p.transpose();
      if (s.pdf == 0.f) continue;
      ASSERT_TRUE(s.direction.allFinite() && std::isfinite(s.distance) && s.radiance.allFinite()) << p.transpose();
      EXPECT_LT(s.direction.y(), 1.f + 1e-6f);
      EXPECT_GT(s.direction.y(), 0.f) << p.transpose();  // toward the panel above
    }
}

TEST(Lights, SphereLightGivesNothingInsideItself) {
  SphereLight sphere;
  sphere.radius = 1.f;
  const LightSample s = sphere.sample({0.1f, 0.2f, 0.f}, 0.3f, 0.6f);
  EXPECT_EQ(s.pdf, 0.f);
  float t = 0.f, pdf = 0.f;
  EXPECT_FALSE(sphere.intersect({0.1f, 0.2f, 0.f}, Vector3f::UnitX(), t, pdf));
}

TEST(Lights, DegenerateLightsEmitNothingAndNeverNaN) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<AreaLight> areas(4);
  areas[0].edge_v = Vector3f::Zero();                 // no area
  areas[1].edge_v = areas[1].edge_u * 2.f;            // collinear edges: no area
  areas[2].radiance = Vector3f::Zero();               // no power
  areas[3].radiance = Vector3f(nan, 1.f, inf);        // nonsense power
  std::vector<SphereLight> spheres(3);
  spheres[0].radius = 0.f;
  spheres[1].radiance = Vector3f::Zero();
  spheres[2].radius = nan;
  std::vector<SunLight> suns(3);
  suns[0].irradiance = Vector3f::Zero();
  suns[1].direction = Vector3f::Zero();
  suns[2].direction = Vector3f(nan, 1.f, 0.f);
  const Vector3f p(0.f, -1.f, 0.f);
  float t = 0.f, pdf = 0.f;
  for (const auto& a : areas) {
    EXPECT_FALSE(a.emits());
    EXPECT_EQ(a.sample(p, 0.5f, 0.5f).pdf, 0.f);
    EXPECT_FALSE(a.intersect(p, Vector3f::UnitY(), t, pdf));
  }
  for (const auto& s : spheres) {
    EXPECT_FALSE(s.emits());
    EXPECT_EQ(s.sample(p, 0.5f, 0.5f).pdf, 0.f);
    EXPECT_FALSE(s.intersect(p, Vector3f::UnitY(), t, pdf));
  }
  for (const auto& s : suns) {
    EXPECT_FALSE(s.emits());
    EXPECT_EQ(s.sample(0.5f, 0.5f).pdf, 0.f);
    EXPECT_EQ(s.pdf(Vector3f::UnitY()), 0.f);
    EXPECT_TRUE(s.radiance().isZero());
  }
  // A point sun (angle 0) or a NaN angle is the smallest cone: finite and still normalised.
  for (double angle : {0.0, static_cast<double>(nan)}) {
    SunLight point_sun;
    point_sun.angular_radius = angle;
    EXPECT_TRUE(point_sun.radiance().allFinite());
    const LightSample s = point_sun.sample(0.5f, 0.5f);
    EXPECT_TRUE(std::isfinite(s.pdf) && s.pdf > 0.f && s.direction.allFinite());
    const auto sample = [&](float u1, float u2) { return point_sun.sample(u1, u2); };
    EXPECT_NEAR(irradiance(Vector3f::UnitY(), sample, 5), 1.0, kIrradianceTolerance);
  }
  // A point exactly on an area light's plane or at a sphere light's surface.
  AreaLight area;
  EXPECT_EQ(area.sample(area.corner, 0.f, 0.f).pdf, 0.f);
  SphereLight sphere;
  EXPECT_EQ(sphere.sample(sphere.center + Vector3f(sphere.radius, 0.f, 0.f), 0.5f, 0.5f).pdf, 0.f);
}

TEST(Lights, EnvironmentClampsNegativeNaNAndInfiniteTexels) {
  cv::Mat image(8, 16, CV_32FC3, cv::Scalar::all(1.0));
  image.at<cv::Vec3f>(0, 0) = {std::numeric_limits<float>::quiet_NaN(), -1.f, 2.f};
  image.at<cv::Vec3f>(3, 4) = {std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(), 1e30f};
  image.at<cv::Vec3f>(5, 9) = {-5.f, -0.f, 0.5f};
  const EnvironmentLight env(image);
  const cv::Mat& clamped = env.image();
  EXPECT_TRUE(cv::checkRange(clamped));
  double lo = 0, hi = 0;
  cv::minMaxLoc(clamped.reshape(1), &lo, &hi);
  EXPECT_GE(lo, 0.0);
  EXPECT_LE(hi, 1e6);
  EXPECT_EQ(clamped.at<cv::Vec3f>(0, 0), cv::Vec3f(0.f, 0.f, 2.f));
  EXPECT_EQ(clamped.at<cv::Vec3f>(3, 4)[0], 0.f);
  EXPECT_EQ(clamped.at<cv::Vec3f>(3, 4)[1], 0.f);
  EXPECT_EQ(clamped.at<cv::Vec3f>(5, 9), cv::Vec3f(0.f, 0.f, 0.5f));
  Rng rng(6, 6);
  for (int i = 0; i < 2000; ++i) {
    float pdf = 0.f;
    const Vector3f d = env.sample(rng.uniform(), rng.uniform(), pdf);
    ASSERT_TRUE(d.allFinite() && std::isfinite(pdf));
    ASSERT_TRUE(env.radiance(d).allFinite());
  }
  const Vector3f bad(std::numeric_limits<float>::quiet_NaN(), 0.f, 1.f);
  EXPECT_TRUE(env.radiance(bad).isZero());
  EXPECT_EQ(env.pdf(bad), 0.f);
  // An all-black (or all-invalid) map is still a valid, dark environment.
  const EnvironmentLight dark(cv::Mat(4, 8, CV_32FC3, cv::Scalar::all(-1.0)));
  float pdf = 0.f;
  EXPECT_TRUE(dark.sample(0.3f, 0.7f, pdf).allFinite());
  EXPECT_TRUE(std::isfinite(pdf) && pdf > 0.f);
}

// The latlong convention other tools must match (a Blender world's truth
// panoramas, SCENE.json's ibl): the centre column looks along -Z, a quarter
// across along -X, three quarters across along +X, the seam along +Z.
TEST(Lights, TheLatlongsCentreColumnIsMinusZAndItsSeamPlusZ) {
  const auto near = [](const Eigen::Vector3f& a, const Eigen::Vector3f& b) { return (a - b).norm() < 1e-5f; };
  EXPECT_TRUE(near(EnvironmentLight::uv_to_direction(0.5f, 0.5f), {0, 0, -1}));
  EXPECT_TRUE(near(EnvironmentLight::uv_to_direction(0.25f, 0.5f), {-1, 0, 0}));
  EXPECT_TRUE(near(EnvironmentLight::uv_to_direction(0.75f, 0.5f), {1, 0, 0}));
  EXPECT_TRUE(near(EnvironmentLight::uv_to_direction(0.0f, 0.5f), {0, 0, 1}));
  EXPECT_TRUE(near(EnvironmentLight::uv_to_direction(0.5f, 0.0f), {0, 1, 0}));
  EXPECT_NEAR(EnvironmentLight::direction_to_uv({0, 0, -1}).x(), 0.5f, 1e-6f);
  EXPECT_NEAR(EnvironmentLight::direction_to_uv({1, 0, 0}).x(), 0.75f, 1e-6f);
}

TEST(Lights, RigOrdersAreaSphereSunDiscPointThenEnvironment) {
  LightRig rig;
  rig.area_lights.resize(2);
  rig.area_lights[1].radiance = Vector3f::Constant(2.f);
  rig.sphere_lights.resize(1);
  rig.suns.resize(1);
  rig.disc_lights.resize(2);
  rig.disc_lights[1].radius = 0.25f;
  rig.point_lights.resize(1);
  rig.environment = std::make_shared<EnvironmentLight>(cv::Mat(2, 4, CV_32FC3, cv::Scalar::all(1.0)));
  ASSERT_EQ(rig.count(), 8);
  EXPECT_EQ(rig.first_sphere(), 2);
  EXPECT_EQ(rig.first_sun(), 3);
  EXPECT_EQ(rig.first_disc(), 4);
  EXPECT_EQ(rig.first_point(), 6);
  EXPECT_EQ(rig.environment_index(), 7);
  EXPECT_EQ(rig.only(1).area_lights.at(0).radiance.x(), 2.f);
  EXPECT_EQ(rig.only(2).sphere_lights.size(), 1u);
  EXPECT_EQ(rig.only(3).suns.size(), 1u);
  EXPECT_EQ(rig.only(5).disc_lights.at(0).radius, 0.25f);
  EXPECT_EQ(rig.only(6).point_lights.size(), 1u);
  EXPECT_TRUE(rig.only(7).environment);
  for (int i = 0; i < rig.count(); ++i) EXPECT_EQ(rig.only(i).count(), 1);
  EXPECT_THROW(rig.only(8), std::out_of_range);
  EXPECT_THROW(rig.only(-1), std::out_of_range);
  rig.environment.reset();
  EXPECT_EQ(rig.count(), 7);
  EXPECT_THROW(rig.only(7), std::out_of_range);
  // A rig without discs and points keeps the old indices (area, sphere, sun, environment).
  LightRig old;
  old.area_lights.resize(1);
  old.sphere_lights.resize(1);
  old.suns.resize(1);
  old.environment = std::make_shared<EnvironmentLight>(cv::Mat(2, 4, CV_32FC3, cv::Scalar::all(1.0)));
  EXPECT_EQ(old.environment_index(), 3);
  EXPECT_TRUE(old.only(3).environment);
}

// Cycles 3.4's spot profile, written out from the angle: cos(theta), times a
// smoothstep over the band of cosines blend * (1 - cos h) inside the edge.
double cycles_spot(double theta, double half_angle, double blend) {
  const double c = std::cos(theta), ch = std::cos(half_angle);
  if (c <= ch) return 0.0;
  const double band = blend * (1.0 - ch);
  if (c - ch >= band) return c;
  const double x = (c - ch) / band;
  return c * x * x * (3.0 - 2.0 * x);
}

// A direction at angle theta from -Y (a spot shining down), turned by phi about it.
Eigen::Vector3d below_at(double theta, double phi = 0.3) {
  return {std::sin(theta) * std::cos(phi), -std::cos(theta), std::sin(theta) * std::sin(phi)};
}

TEST(Lights, SpotConeFollowsCyclesProfile) {
  SpotCone cone;  // 60 degrees wide (Blender spot_size), blend 0.5, shining down
  cone.half_angle = kPi / 6;
  cone.blend = 0.5;
  for (double deg : {0.0, 5.0, 15.0, 20.0, 25.0, 29.0, 29.9, 30.0, 30.1, 45.0, 90.0, 135.0, 180.0}) {
    const double theta = deg * kPi / 180.0;
    EXPECT_NEAR(cone.attenuation(below_at(theta)), cycles_spot(theta, cone.half_angle, cone.blend), 1e-6) << deg;
    EXPECT_NEAR(cone.attenuation(7.0 * below_at(theta)), cone.attenuation(below_at(theta)), 1e-12) << "scale-free";
  }
  // Inside the blend the profile lies strictly between 0 and cos(theta).
  const double in_blend = cone.attenuation(below_at(25.0 * kPi / 180.0));
  EXPECT_GT(in_blend, 0.1);
  EXPECT_LT(in_blend, std::cos(25.0 * kPi / 180.0) - 0.1);
  // A hard edge (blend 0) is cos(theta) right up to the edge.
  cone.blend = 0.0;
  EXPECT_NEAR(cone.attenuation(below_at(29.9 * kPi / 180.0)), std::cos(29.9 * kPi / 180.0), 1e-9);
  EXPECT_EQ(cone.attenuation(below_at(30.1 * kPi / 180.0)), 0.0);
}

// A point light: E = I cos / d^2 from one (exact) sample, a delta with pdf 1.
TEST(Lights, PointLightIrradianceIsIntensityCosOverDistanceSquared) {
  PointLight light;
  light.position = {0.3f, 2.f, -0.4f};
  light.intensity = Vector3f(5.f, 4.f, 3.f);
  const Vector3f p(0.1f, 0.f, 0.2f);
  const LightSample s = light.sample(p);
  ASSERT_TRUE(s.delta);
  ASSERT_EQ(s.pdf, 1.f);
  const Vector3f to = light.position - p;
  const double d2 = to.squaredNorm();
  EXPECT_NEAR(s.distance, std::sqrt(d2), 1e-6);
  EXPECT_NEAR((s.direction - to.normalized()).norm(), 0.f, 1e-6f);
  for (const Vector3f& n : {Vector3f(Vector3f::UnitY()), Vector3f(0.6f, 0.8f, 0.f), Vector3f(-0.8f, 0.6f, 0.f)}) {
    const double cos_theta = std::max(0.f, to.normalized().dot(n));
    const auto sample = [&](float u1, float u2) { return light.sample(p, u1, u2); };
    EXPECT_NEAR(irradiance(n, sample, 7), 5.0 * cos_theta / d2, 1e-5) << n.transpose();
  }
  EXPECT_NEAR(s.radiance.y(), 4.0 / d2, 1e-5);
}

// A spot of radius 0 (a point in a cone): E = I spot(theta) cos / d^2 inside,
// in the blend and outside the cone.
TEST(Lights, PointSpotIrradianceInsideInTheBlendAndOutsideTheCone) {
  PointLight light;
  light.position = {0.f, 2.f, 0.f};
  light.intensity = Vector3f::Constant(8.f);
  SpotCone cone;
  cone.half_angle = kPi / 6;
  cone.blend = 0.5;
  light.spot = cone;
  for (double deg : {0.0, 10.0, 25.0, 28.0, 35.0, 60.0}) {
    const double theta = deg * kPi / 180.0;
    // Floor points (y = 0) seen from the light at theta.
    const double r = 2.0 * std::tan(theta);
    const Vector3f p(static_cast<float>(r), 0.f, 0.f);
    const double d2 = 4.0 + r * r;
    const double expected = 8.0 * cycles_spot(theta, cone.half_angle, cone.blend) * std::cos(theta) / d2;
    const auto sample = [&](float u1, float u2) { return light.sample(p, u1, u2); };
    EXPECT_NEAR(irradiance(Vector3f::UnitY(), sample, 8), expected, 1e-6 + 1e-5 * expected) << deg;
    if (deg > 30.0) {
      EXPECT_EQ(light.sample(p).pdf, 0.f) << "outside the cone: no sample, no shadow ray";
    }
  }
}

// A spot of radius r > 0 is a sphere light whose radiance a point receives
// scaled by the cone's attenuation along centre -> point: facing it,
// E = pi L (r/d)^2 spot(theta).
TEST(Lights, SphereSpotIrradianceIsTheSpheresTimesTheCone) {
  SphereLight light;
  light.center = {0.f, 2.f, 0.f};
  light.radius = 0.1f;
  light.radiance = Vector3f::Constant(50.f);
  SpotCone cone;
  cone.half_angle = kPi / 4;
  cone.blend = 0.3;
  light.spot = cone;
  for (double deg : {0.0, 30.0, 42.0, 50.0}) {
    const double theta = deg * kPi / 180.0;
    const Eigen::Vector3d p3 = Eigen::Vector3d(0, 2, 0) + 2.5 * below_at(theta);
    const Vector3f p = p3.cast<float>();
    const Vector3f facing = (light.center - p).normalized();
    const double expected = kPi * 50.0 * std::pow(0.1 / 2.5, 2) * cycles_spot(theta, cone.half_angle, cone.blend);
    const auto sample = [&](float u1, float u2) { return light.sample(p, u1, u2); };
    EXPECT_NEAR(irradiance(facing, sample, 9), expected, 1e-6 + expected * kIrradianceTolerance) << deg;
    // Rays from p that meet the sphere carry the same radiance as its samples.
    EXPECT_NEAR(light.radiance_toward(p).x(), 50.0 * cycles_spot(theta, cone.half_angle, cone.blend), 1e-3) << deg;
  }
}

// A one-sided disc of radiance L, radius r, seen on its axis from distance d:
// E = pi L r^2 / (r^2 + d^2), whatever the disc's orientation in the world.
TEST(Lights, DiscIrradianceOnItsAxisIsPiLr2OverR2PlusD2) {
  struct Case {
    float radius, distance;
    Vector3f normal;
  };
  for (const Case& c : {Case{0.5f, 1.f, {0.f, -1.f, 0.f}}, Case{0.2f, 2.f, {0.3f, -1.f, 0.5f}},
                        Case{1.f, 1.f, {0.f, 0.f, 1.f}}}) {
    DiscLight disc;
    disc.normal = c.normal.normalized();
    disc.centre = Vector3f(0.1f, 0.4f, -0.2f);
    disc.radius = c.radius;
    disc.radiance = Vector3f::Constant(3.f);
    const Vector3f p = disc.centre + c.distance * disc.normal;
    const double r2 = c.radius * c.radius, d2 = c.distance * c.distance;
    const double expected = kPi * 3.0 * r2 / (r2 + d2);
    const auto sample = [&](float u1, float u2) { return disc.sample(p, u1, u2); };
    EXPECT_NEAR(irradiance(-disc.normal, sample, 10), expected, expected * 0.01) << c.radius << " " << c.distance;
    // Behind it, nothing.
    EXPECT_EQ(disc.sample(disc.centre - c.distance * disc.normal, 0.3f, 0.7f).pdf, 0.f);
  }
}

TEST(Lights, DiscSamplesHitTheDiscWithTheSamePdf) {
  DiscLight disc;
  disc.centre = {0.2f, 2.f, -0.3f};
  disc.normal = Vector3f(0.2f, -1.f, 0.1f).normalized();
  disc.radius = 0.4f;
  const Vector3f p(0.1f, 0.f, 0.05f);
  Rng rng(11, 11);
  for (int i = 0; i < 2000; ++i) {
    const LightSample s = disc.sample(p, rng.uniform(), rng.uniform());
    ASSERT_GT(s.pdf, 0.f);
    EXPECT_FALSE(s.delta);
    // The sampled point lies on the disc.
    const Vector3f q = p + s.distance * s.direction - disc.centre;
    EXPECT_NEAR(q.dot(disc.normal), 0.f, 1e-5f);
    EXPECT_LE(q.norm(), disc.radius * (1.f + 1e-5f));
    float t = 0.f, pdf = 0.f;
    ASSERT_TRUE(disc.intersect(p, s.direction, t, pdf));
    EXPECT_NEAR(t, s.distance, 1e-4f);
    EXPECT_NEAR(pdf, s.pdf, kPdfAgreement * s.pdf);
  }
  float t = 0.f, pdf = 0.f;
  EXPECT_FALSE(disc.intersect(p, -Vector3f::UnitY(), t, pdf));                   // away from it
  EXPECT_FALSE(disc.intersect({0.2f, 3.f, -0.3f}, -Vector3f::UnitY(), t, pdf));  // at its back
  EXPECT_FALSE(disc.intersect(p, (Vector3f(1.5f, 2.f, -0.3f) - p).normalized(), t, pdf));  // past its rim
  // The pdf integrates to 1 over the disc's solid angle: E[1/pdf] over its samples is that solid angle,
  // and on the axis it is 2 pi (1 - d / sqrt(d^2 + r^2)).
  DiscLight facing;
  facing.centre = {0.f, 1.f, 0.f};
  facing.radius = 0.5f;
  double omega = 0.0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) omega += 1.0 / facing.sample(Vector3f::Zero(), rng.uniform(), rng.uniform()).pdf / n;
  EXPECT_NEAR(omega, 2 * kPi * (1.0 - 1.0 / std::sqrt(1.25)), 0.005 * omega);
}

}  // namespace
}  // namespace propcam::render
