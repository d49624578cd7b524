#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <numbers>

#include "worlds/light_probe.h"
#include "propcam/render/mesh_shapes.h"

namespace propcam::firmware {
namespace {

constexpr double kPi = std::numbers::pi;

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / kPi;
}

// A level floor of `albedo` (a square of half side `half` at y = 0), optionally a roof over the origin.
std::unique_ptr<render::Scene> floor_scene(float albedo, bool roof_over_origin = false, float half = 10.f) {
  render::Mesh mesh;
  render::Material m;
  m.type = render::Material::Type::Diffuse;
  m.albedo = Eigen::Vector3f::Constant(albedo);
  mesh.materials.push_back(m);
  using V = Eigen::Vector3f;
  render::add_quad(mesh, V(-half, 0, half), V(half, 0, half), V(half, 0, -half), V(-half, 0, -half), 0, 1.f);
  if (roof_over_origin) render::add_box(mesh, V(-2, 1.5f, -2), V(2, 1.6f, 2), 0);
  auto scene = std::make_unique<render::Scene>();
  scene->add_mesh(std::move(mesh), render::Layer::Background);
  scene->commit();
  return scene;
}

TEST(LightProbe, SphereLightDirectionAndIrradiance) {
  const auto scene = floor_scene(0.f);  // black floor: only the light
  const Eigen::Vector3f point(0, 0.5f, 0);
  const Eigen::Vector3d axis = Eigen::Vector3d(0.5, 0.8, -0.3).normalized();
  render::LightRig rig;
  render::SphereLight light;
  light.center = point + 3.f * axis.cast<float>();
  light.radius = 0.3f;
  light.radiance = Eigen::Vector3f::Constant(10.f);
  rig.sphere_lights.push_back(light);
  const LightMoments m = probe_light_moments(*scene, rig, point, 32, 16, 1);
  const double sin2 = 0.1 * 0.1;  // sin of the angular radius: 0.3 / 3
  const double expected_vector = 10.0 * kPi * sin2;
  EXPECT_LT(angle_deg(m.vector, axis), 1.0);
  EXPECT_NEAR(m.vector.norm() / expected_vector, 1.0, 0.02);
  EXPECT_NEAR(m.irradiance_up / (expected_vector * axis.y()), 1.0, 0.02);
  EXPECT_NEAR(m.total / (10.0 * 2 * kPi * (1 - std::sqrt(1 - sin2))), 1.0, 0.02);
}

TEST(LightProbe, BrightSmallLightIsNotClamped) {
  // A bulb far brighter than the path tracer's per-sample clamp (64).
  const auto scene = floor_scene(0.f);
  const Eigen::Vector3f point(0, 0.5f, 0);
  const Eigen::Vector3d axis = Eigen::Vector3d(-0.2, 1.0, 0.4).normalized();
  render::LightRig rig;
  render::SphereLight light;
  light.center = point + 2.f * axis.cast<float>();
  light.radius = 0.05f;
  light.radiance = Eigen::Vector3f::Constant(5000.f);
  rig.sphere_lights.push_back(light);
  const LightMoments m = probe_light_moments(*scene, rig, point, 32, 32, 2);
  const double sin2 = 0.025 * 0.025;
  EXPECT_LT(angle_deg(m.vector, axis), 1.0);
  EXPECT_NEAR(m.irradiance_up / (5000.0 * kPi * sin2 * axis.y()), 1.0, 0.02);
}

TEST(LightProbe, SunIsAddedOnceAndItsBounceCounts) {
  // A grey floor lit by a sun: the disc is added analytically, the floor's
  // bounce comes from below (its radiance 0.5 E cos / pi over ~the whole
  // lower hemisphere: a moment of -0.5 E cos along Y).
  const auto scene = floor_scene(0.5f);
  const Eigen::Vector3f point(0, 0.5f, 0);
  const Eigen::Vector3d d = Eigen::Vector3d(-0.3, 0.7, 0.4).normalized();
  render::LightRig rig;
  render::SunLight sun;
  sun.direction = d.cast<float>();
  sun.irradiance = Eigen::Vector3f::Constant(5.f);
  rig.suns.push_back(sun);
  const LightMoments m = probe_light_moments(*scene, rig, point, 24, 16, 3);
  EXPECT_NEAR(m.irradiance_up / (5.0 * d.y()), 1.0, 0.02);
  const Eigen::Vector3d expected = 5.0 * d - Eigen::Vector3d(0, 0.5 * 5.0 * d.y(), 0);
  EXPECT_LT(angle_deg(m.vector, expected), 3.0);
  EXPECT_NEAR(m.vector.norm() / expected.norm(), 1.0, 0.05);
}

TEST(LightProbe, AreaLightIsCountedOnceOverAGreyFloor) {
  // A ceiling panel above the point: over a grey floor the upward irradiance
  // is the panel's alone (a light seen directly must not also come through
  // the face renders), and the floor's bounce pulls the vector down.
  render::LightRig rig;
  render::AreaLight panel;
  panel.corner = Eigen::Vector3f(-0.3f, 2.5f, -0.3f);
  panel.edge_u = Eigen::Vector3f(0.6f, 0, 0);
  panel.edge_v = Eigen::Vector3f(0, 0, 0.6f);  // u x v = -Y: emits downward
  panel.radiance = Eigen::Vector3f::Constant(20.f);
  rig.area_lights.push_back(panel);
  const Eigen::Vector3f point(0.2f, 0.5f, 0.1f);
  const LightMoments black = probe_light_moments(*floor_scene(0.f), rig, point, 24, 16, 8);
  const LightMoments grey = probe_light_moments(*floor_scene(0.5f), rig, point, 24, 16, 8);
  // The panel subtends ~0.09 sr at 2 m: irradiance ~ 20 * 0.09 * cos.
  EXPECT_GT(black.irradiance_up, 1.5);
  EXPECT_LT(black.irradiance_up, 2.0);
  EXPECT_NEAR(grey.irradiance_up / black.irradiance_up, 1.0, 0.01);
  EXPECT_LT(grey.vector.y(), black.vector.y());
  EXPECT_GT(grey.total, black.total);
  // The floor (albedo 0.5) sends back at most 0.5 of its brightest
  // irradiance, E(2.5 m) = (2 / 2.5)^2 of the point's: a moment below
  // 0.32 of the point's irradiance, and well above nothing.
  const double bounce = black.vector.y() - grey.vector.y();
  EXPECT_GT(bounce, 0.1 * black.irradiance_up);
  EXPECT_LT(bounce, 0.33 * black.irradiance_up);
}

TEST(LightProbe, OccludedSunGivesNothing) {
  const auto scene = floor_scene(0.f, /*roof_over_origin=*/true);
  render::LightRig rig;
  render::SunLight sun;
  sun.direction = Eigen::Vector3f(0.1f, 1.f, 0.1f);
  sun.irradiance = Eigen::Vector3f::Constant(100.f);
  rig.suns.push_back(sun);
  const LightMoments m = probe_light_moments(*scene, rig, Eigen::Vector3f(0, 0.5f, 0), 16, 4, 4);
  EXPECT_LT(m.total, 1e-6);
  EXPECT_TRUE(m.vector.allFinite());
}

// A sun that comes through windows reaches the point only through one.
TEST(LightProbe, ASunThroughAWindowReachesOnlyWhatTheWindowLets) {
  const auto scene = floor_scene(0.f);
  render::LightRig rig;
  render::SunLight sun;
  sun.direction = Eigen::Vector3f(0.f, 1.f, 0.f);
  sun.irradiance = Eigen::Vector3f::Constant(10.f);
  sun.through_portals = true;
  rig.suns.push_back(sun);
  // A window 2 m up over x, z in [-0.5, 0.5].
  rig.portals.push_back({Eigen::Vector3f(-0.5f, 2.f, -0.5f), Eigen::Vector3f(1.f, 0.f, 0.f), Eigen::Vector3f(0.f, 0.f, 1.f)});
  const LightMoments under = probe_light_moments(*scene, rig, Eigen::Vector3f(0, 0.5f, 0), 8, 1, 4);
  EXPECT_NEAR(under.total, 10.0, 1e-3);
  EXPECT_GT(under.vector.y(), 9.9);
  const LightMoments beside = probe_light_moments(*scene, rig, Eigen::Vector3f(2.f, 0.5f, 0), 8, 1, 4);
  EXPECT_LT(beside.total, 1e-6);
}

TEST(LightProbe, UniformSkyOverBlackFloor) {
  const auto scene = floor_scene(0.f, false, 1000.f);
  render::LightRig rig;
  rig.environment = std::make_shared<render::EnvironmentLight>(cv::Mat(32, 64, CV_32FC3, cv::Scalar::all(0.7)));
  const LightMoments m = probe_light_moments(*scene, rig, Eigen::Vector3f(0, 0.5f, 0), 24, 8, 5);
  // The floor hides all of the lower hemisphere but a sliver at the horizon (0.5 m below, 1 km out).
  EXPECT_NEAR(m.irradiance_up / (kPi * 0.7), 1.0, 0.02);
  EXPECT_NEAR(m.total / (2 * kPi * 0.7), 1.0, 0.03);
  EXPECT_LT(angle_deg(m.vector, Eigen::Vector3d::UnitY()), 2.0);
  EXPECT_NEAR(m.vector.y() / (kPi * 0.7), 1.0, 0.03);
}

TEST(LightProbe, LatlongOfUniformAndOfOnePatch) {
  const LightMoments u = latlong_light_moments(cv::Mat(64, 128, CV_32FC3, cv::Scalar::all(2.0)));
  EXPECT_NEAR(u.total, 4 * kPi * 2.0, 1e-3);
  EXPECT_NEAR(u.irradiance_up, kPi * 2.0, 0.02);
  EXPECT_LT(u.vector.norm(), 1e-3);

  // A bright patch three quarters across (+X in the EnvironmentLight
  // convention: the centre column looks along -Z) and 30 degrees above the horizon.
  cv::Mat map(64, 128, CV_32FC3, cv::Scalar::all(0));
  const int col = 96, row = 32 - 11;  // row centre at theta ~ 60 deg from +Y
  map(cv::Rect(col - 1, row - 1, 2, 2)).setTo(cv::Scalar::all(1000.0));
  const LightMoments p = latlong_light_moments(map);
  const Eigen::Vector3d expected = render::EnvironmentLight::uv_to_direction(col / 128.f, row / 64.f).cast<double>();
  EXPECT_LT(angle_deg(p.vector, expected), 2.0);
  EXPECT_GT(p.vector.x(), 0.8 * p.vector.norm());

  // Negative and non-finite texels count as nothing.
  cv::Mat bad(8, 16, CV_32FC3, cv::Scalar::all(-1.0));
  bad.at<cv::Vec3f>(2, 3) = cv::Vec3f(std::numeric_limits<float>::quiet_NaN(), INFINITY, 1.f);
  const LightMoments b = latlong_light_moments(bad);
  EXPECT_TRUE(b.vector.allFinite());
  EXPECT_GE(b.total, 0.0);
  EXPECT_THROW(latlong_light_moments(cv::Mat()), std::invalid_argument);
}

TEST(LightProbe, CubeProbeAgreesWithLatlongMoments) {
  // The same panorama as an environment, nothing around the point.
  cv::Mat map(64, 128, CV_32FC3, cv::Scalar::all(0.2));
  map(cv::Rect(40, 10, 8, 6)).setTo(cv::Scalar(30, 25, 20));
  render::Mesh speck;  // a scene needs geometry: one tiny triangle far below
  speck.materials.emplace_back();
  speck.positions = {{0, -100, 0}, {0.01f, -100, 0}, {0, -100, 0.01f}};
  speck.triangles = {{0, 1, 2}};
  speck.material_ids = {0};
  render::Scene scene;
  scene.add_mesh(std::move(speck), render::Layer::Background);
  scene.commit();
  render::LightRig rig;
  rig.environment = std::make_shared<render::EnvironmentLight>(map);
  const LightMoments cube = probe_light_moments(scene, rig, Eigen::Vector3f(0, 1, 0), 32, 16, 6);
  const LightMoments pano = latlong_light_moments(map);
  EXPECT_LT(angle_deg(cube.vector, pano.vector), 3.0);
  EXPECT_NEAR(cube.vector.norm() / pano.vector.norm(), 1.0, 0.05);
  EXPECT_NEAR(cube.irradiance_up / pano.irradiance_up, 1.0, 0.03);
  EXPECT_NEAR(cube.total / pano.total, 1.0, 0.03);
}

TEST(LightProbe, DarkRigAndBadArguments) {
  const auto scene = floor_scene(0.5f);
  const LightMoments m = probe_light_moments(*scene, render::LightRig{}, Eigen::Vector3f(0, 0.5f, 0), 8, 2, 7);
  EXPECT_EQ(m.total, 0.0);
  EXPECT_TRUE(m.vector.allFinite());
  EXPECT_THROW(probe_light_moments(*scene, render::LightRig{}, Eigen::Vector3f(0, 0.5f, 0), 1, 2, 7), std::invalid_argument);
  EXPECT_THROW(probe_light_moments(*scene, render::LightRig{}, Eigen::Vector3f(NAN, 0, 0), 8, 2, 7), std::invalid_argument);
}

}  // namespace
}  // namespace propcam::firmware
