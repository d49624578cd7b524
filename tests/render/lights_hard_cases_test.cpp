// Hard cases of the point, spot and disc lights: a disc of no size, cones of
// 0 and 180 degrees, a point light at the shading point, nonsense fields.
// Every one gives a finite answer (no NaN, no infinity), in isolation and in
// a render.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "propcam/render/lights.h"
#include "propcam/render/path_tracer.h"

namespace propcam::render {
namespace {

using Eigen::Vector3f;

constexpr double kPi = std::numbers::pi;
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

// A sample is either nothing (pdf 0) or finite throughout.
void expect_finite(const LightSample& s) {
  ASSERT_TRUE(std::isfinite(s.pdf) && s.pdf >= 0.f);
  if (s.pdf == 0.f) return;
  EXPECT_TRUE(s.direction.allFinite());
  EXPECT_TRUE(std::isfinite(s.distance));
  EXPECT_TRUE(s.radiance.allFinite());
  EXPECT_GE(s.radiance.minCoeff(), 0.f);
}

// Points around a light at the origin, including on it and very near it.
std::vector<Vector3f> probe_points() {
  return {{0.f, 0.f, 0.f},   {0.f, -1e-7f, 0.f}, {0.f, -1e-5f, 0.f}, {0.f, -1.f, 0.f},
          {1.f, 0.f, 0.f},   {0.f, 1.f, 0.f},    {1e-7f, 0.f, 0.f},  {3.f, -2.f, 1.f},
          {0.f, -1e6f, 0.f}, {1e-30f, 0.f, 0.f}};
}

TEST(LightsHardCases, ZeroSizeAndNonsenseDiscsEmitNothing) {
  std::vector<DiscLight> discs(7);
  discs[0].radius = 0.f;
  discs[1].radius = 1e-7f;  // below kMinDiscLightRadius
  discs[2].radius = kNaN;
  discs[3].radius = -1.f;
  discs[4].normal = Vector3f::Zero();
  discs[5].normal = Vector3f(kNaN, -1.f, 0.f);
  discs[6].radiance = Vector3f(kInf, 1.f, 1.f);
  float t = 0.f, pdf = 0.f;
  for (const DiscLight& d : discs) {
    EXPECT_FALSE(d.emits());
    for (const Vector3f& p : probe_points()) {
      const LightSample s = d.sample(p, 0.5f, 0.5f);
      EXPECT_EQ(s.pdf, 0.f);
      EXPECT_FALSE(d.intersect(p, -Vector3f::UnitY(), t, pdf));
      EXPECT_FALSE(d.intersect(p, Vector3f::UnitY(), t, pdf));
    }
  }
  // A good disc seen from its own plane (edge-on), from its centre, from far away.
  DiscLight disc;
  for (const Vector3f& p : probe_points())
    for (float u : {0.f, 0.5f, 0.999999f}) expect_finite(disc.sample(p, u, 1.f - u));
  EXPECT_EQ(disc.sample({1.f, 0.f, 0.f}, 0.3f, 0.3f).pdf, 0.f);  // in its plane
  EXPECT_FALSE(disc.intersect({1.f, 0.f, 0.f}, -Vector3f::UnitX(), t, pdf));
}

TEST(LightsHardCases, SpotConesOfZeroAndOneHundredEightyDegrees) {
  SpotCone closed;
  closed.half_angle = 0.0;  // cone_angle_deg 0: no direction is inside
  SpotCone open;
  open.half_angle = kPi / 2;  // cone_angle_deg 180: the lower hemisphere
  for (double blend : {0.0, 0.5, 1.0}) {
    closed.blend = open.blend = blend;
    EXPECT_EQ(closed.attenuation({0.0, -1.0, 0.0}), 0.0);  // not even on the axis
    EXPECT_EQ(closed.attenuation({1e-9, -1.0, 0.0}), 0.0);
    // The open cone: Cycles' cos(theta) times the blend's smoothstep over all of (0, 1].
    EXPECT_NEAR(open.attenuation({0.0, -1.0, 0.0}), 1.0, 1e-12);
    const double c = std::cos(1.0);
    const double x = blend > 0.0 ? std::min(1.0, c / blend) : 1.0;
    EXPECT_NEAR(open.attenuation({std::sin(1.0), -c, 0.0}), c * x * x * (3.0 - 2.0 * x), 1e-9) << blend;
    EXPECT_EQ(open.attenuation({1.0, 0.0, 0.0}), 0.0);   // at 90 degrees
    EXPECT_EQ(open.attenuation({0.0, 1.0, 0.0}), 0.0);   // behind
    EXPECT_EQ(open.attenuation({0.0, 0.0, 0.0}), 0.0);   // no direction
    EXPECT_EQ(open.attenuation({kNaN, -1.0, 0.0}), 0.0);
  }
  // Out-of-range angles behave as the nearest valid one.
  SpotCone wide = open;
  wide.half_angle = 4.0;
  EXPECT_EQ(wide.attenuation({0.0, 1.0, 0.0}), 0.0);
  EXPECT_EQ(wide.attenuation({0.3, -1.0, 0.0}), open.attenuation({0.3, -1.0, 0.0}));
  SpotCone negative = open;
  negative.half_angle = -1.0;
  EXPECT_EQ(negative.attenuation({0.0, -1.0, 0.0}), 0.0);

  // As lights: the closed cone sends nothing (no sample, no shadow ray), the open one the lower hemisphere.
  PointLight point;
  point.spot = closed;
  SphereLight sphere;
  sphere.spot = closed;
  for (const Vector3f& p : probe_points()) {
    EXPECT_EQ(point.sample(p).pdf, 0.f);
    EXPECT_EQ(sphere.sample(p, 0.5f, 0.5f).pdf, 0.f);
  }
  point.spot = sphere.spot = open;
  EXPECT_NEAR(point.sample({0.f, -2.f, 0.f}).radiance.x(), 1.f / 4.f, 1e-6f);
  EXPECT_EQ(point.sample({0.f, 2.f, 0.f}).pdf, 0.f);
  EXPECT_EQ(point.sample({2.f, 0.f, 0.f}).pdf, 0.f);
  for (const Vector3f& p : probe_points()) {
    expect_finite(point.sample(p));
    expect_finite(sphere.sample(p, 0.25f, 0.75f));
  }
}

TEST(LightsHardCases, PointLightAtTheShadingPointGivesNothingFinite) {
  PointLight light;
  light.position = {0.5f, 1.f, -0.5f};
  light.intensity = Vector3f::Constant(1e3f);
  const LightSample at = light.sample(light.position);
  EXPECT_EQ(at.pdf, 0.f);
  EXPECT_TRUE(at.radiance.allFinite());
  EXPECT_EQ(light.sample(light.position + Vector3f(0.f, 1e-7f, 0.f)).pdf, 0.f);  // nearer than 1e-6 m
  // Just beyond: a large but finite I / d^2.
  const LightSample near = light.sample(light.position + Vector3f(0.f, -1e-5f, 0.f));
  expect_finite(near);
  EXPECT_GT(near.radiance.x(), 1e12f);
  // An intensity whose I / d^2 overflows a float gives nothing rather than infinity.
  light.intensity = Vector3f::Constant(1e30f);
  expect_finite(light.sample(light.position + Vector3f(0.f, -1e-5f, 0.f)));
  // Nonsense fields: no light.
  std::vector<PointLight> bads(5);
  bads[0].position = Vector3f(kNaN, 0.f, 0.f);
  bads[1].intensity = Vector3f(kNaN, 1.f, 1.f);
  bads[2].intensity = Vector3f::Zero();
  bads[3].spot = SpotCone{Vector3f::Zero(), kPi / 4, 0.1};
  bads[4].spot = SpotCone{-Vector3f::UnitY(), static_cast<double>(kNaN), 0.1};
  for (const PointLight& bad : bads) {
    EXPECT_FALSE(bad.emits());
    EXPECT_EQ(bad.sample(Vector3f(0.f, -1.f, 0.f)).pdf, 0.f);
  }
}

// The same hard cases in a render: a floor with a point light lying on it, a
// spot of cone 0, a spot of cone 180 at the floor, a disc of no size: finite
// everywhere, and the lights that emit nothing add nothing.
TEST(LightsHardCases, DegenerateNewLightsRenderFinite) {
  Mesh floor;
  floor.positions = {{-2, 0, -2}, {2, 0, -2}, {2, 0, 2}, {-2, 0, 2}};
  floor.triangles = {{0, 2, 1}, {0, 3, 2}};
  floor.material_ids = {0, 0};
  floor.materials.emplace_back();
  Scene scene;
  scene.add_mesh(floor, Layer::Background);
  scene.commit();
  PinholeCamera camera;
  camera.width = camera.height = 16;
  camera.fx = camera.fy = 16;
  camera.cx = camera.cy = 7.5;
  camera.R_world_from_cam << 1, 0, 0, 0, 0, -1, 0, 1, 0;  // looking down
  camera.center_world = {0, 2, 0};
  RenderSettings settings;
  settings.samples_per_pixel = 4;
  settings.max_bounces = 2;

  LightRig nothing;
  nothing.disc_lights.push_back(DiscLight{Vector3f(0.f, 1.f, 0.f), -Vector3f::UnitY(), 0.f, Vector3f::Ones(), true});
  PointLight shut;
  shut.position = {0.f, 1.f, 0.f};
  shut.spot = SpotCone{-Vector3f::UnitY(), 0.0, 0.5};
  nothing.point_lights.push_back(shut);
  SphereLight shut_sphere;
  shut_sphere.center = {0.f, 1.f, 0.f};
  shut_sphere.spot = shut.spot;
  nothing.sphere_lights.push_back(shut_sphere);
  const cv::Mat dark = render_image(scene, camera, nothing, settings);
  EXPECT_EQ(cv::norm(dark, cv::NORM_INF), 0.0);

  LightRig on_floor;
  on_floor.point_lights.push_back(PointLight{Vector3f(0.f, 0.f, 0.f), Vector3f::Constant(5.f), std::nullopt});
  PointLight half = on_floor.point_lights[0];
  half.position = {0.3f, 1e-7f, 0.2f};
  half.spot = SpotCone{-Vector3f::UnitY(), kPi / 2, 1.0};
  on_floor.point_lights.push_back(half);
  on_floor.disc_lights = nothing.disc_lights;
  const cv::Mat lit = render_image(scene, camera, on_floor, settings);
  EXPECT_TRUE(cv::checkRange(lit));
  // A point on the floor grazes it: cos 0 at every floor point, so its light
  // there is 0 up to the floor's round-off, never NaN.
  EXPECT_LT(cv::mean(lit)[0], 1.0);
  const std::vector<cv::Mat> layers = render_background_light_images(scene, camera, on_floor, settings);
  for (const cv::Mat& layer : layers) EXPECT_TRUE(cv::checkRange(layer));
}

// A portal is crossed only at t > 0 inside its parallelogram; a flat,
// non-finite or edge-on window lets nothing through, and a rig whose
// outside light needs a window it does not have receives none.
TEST(LightsHardCases, PortalsLetThroughOnlyTheRaysThatCrossThem) {
  Portal window;
  window.corner = {0.f, 2.f, 0.f};
  window.edge_u = {1.f, 0.f, 0.f};
  window.edge_v = {0.f, 0.f, 1.f};
  const Eigen::Vector3f up = Eigen::Vector3f::UnitY();
  EXPECT_TRUE(window.crossed_by({0.5f, 0.f, 0.5f}, up));
  EXPECT_TRUE(window.crossed_by({0.5f, 3.f, 0.5f}, -up));          // from the other side
  EXPECT_FALSE(window.crossed_by({0.5f, 0.f, 0.5f}, -up));         // behind the ray
  EXPECT_FALSE(window.crossed_by({1.5f, 0.f, 0.5f}, up));          // beside it
  EXPECT_FALSE(window.crossed_by({0.5f, 2.f, 0.5f}, {1.f, 0.f, 0.f}));  // in its plane
  EXPECT_FALSE(window.crossed_by({0.5f, 0.f, 0.5f}, {std::nanf(""), 1.f, 0.f}));
  EXPECT_FALSE(window.crossed_by({0.5f, 0.f, 0.5f}, Eigen::Vector3f::Zero()));
  Portal flat = window;
  flat.edge_v = {2.f, 0.f, 0.f};  // parallel edges: no area
  EXPECT_FALSE(flat.valid());
  EXPECT_FALSE(flat.crossed_by({0.5f, 0.f, 0.f}, up));
  Portal nowhere = window;
  nowhere.corner = {std::numeric_limits<float>::infinity(), 2.f, 0.f};
  EXPECT_FALSE(nowhere.valid());
  EXPECT_FALSE(nowhere.crossed_by({0.5f, 0.f, 0.5f}, up));

  LightRig rig;
  EXPECT_TRUE(rig.arrives_from_outside({0.5f, 0.f, 0.5f}, up, false));
  EXPECT_FALSE(rig.arrives_from_outside({0.5f, 0.f, 0.5f}, up, true));
  rig.portals = {flat, window};
  EXPECT_TRUE(rig.arrives_from_outside({0.5f, 0.f, 0.5f}, up, true));
  EXPECT_FALSE(rig.arrives_from_outside({-0.5f, 0.f, 0.5f}, up, true));
  rig.suns.push_back(SunLight{});
  EXPECT_EQ(rig.only(0).portals.size(), 2u);
}

}  // namespace
}  // namespace propcam::render
