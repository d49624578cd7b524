#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>

#include "bsdf.h"
#include "propcam/render/mesh_shapes.h"
#include "propcam/render/path_tracer.h"
#include "propcam/render/synthetic_room.h"
#include "sampling.h"

namespace propcam::render {
namespace {

Mesh floor_quad(float half, const Material& material) {
  Mesh m;
  m.positions = {{-half, 0, -half}, {half, 0, -half}, {half, 0, half}, {-half, 0, half}};
  m.triangles = {{0, 2, 1}, {0, 3, 2}};  // counter-clockwise seen from above: the front faces +Y
  m.material_ids = {0, 0};
  m.materials.push_back(material);
  return m;
}

Mesh floor_quad(float half, const Eigen::Vector3f& albedo) {
  Material mat;
  mat.albedo = albedo;
  return floor_quad(half, mat);
}

// A flat-shaded UV sphere, outward-wound.
Mesh sphere_mesh(const Eigen::Vector3f& center, float radius, const Material& material, int rings = 24,
                 int segments = 48) {
  Mesh m;
  const float pi = std::numbers::pi_v<float>;
  for (int i = 0; i <= rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const float theta = pi * i / rings, phi = 2.f * pi * j / segments;
      m.positions.push_back(center + radius * Eigen::Vector3f(std::sin(theta) * std::cos(phi), std::cos(theta),
                                                              std::sin(theta) * std::sin(phi)));
    }
  const auto add = [&](int a, int b, int c) {
    const Eigen::Vector3f n = (m.positions[b] - m.positions[a]).cross(m.positions[c] - m.positions[a]);
    if (n.norm() < 1e-12f) return;  // collapsed at a pole
    const Eigen::Vector3f mid = (m.positions[a] + m.positions[b] + m.positions[c]) / 3.f - center;
    if (n.dot(mid) < 0.f) std::swap(b, c);
    m.triangles.emplace_back(a, b, c);
    m.material_ids.push_back(0);
  };
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const int a = i * segments + j, b = i * segments + (j + 1) % segments;
      const int c = a + segments, d = b + segments;
      add(a, b, d);
      add(a, d, c);
    }
  m.materials.push_back(material);
  return m;
}

Material material(Material::Type type, float roughness, const Eigen::Vector3f& albedo = Eigen::Vector3f::Ones()) {
  Material m;
  m.type = type;
  m.roughness = roughness;
  m.albedo = albedo;
  return m;
}

std::shared_ptr<EnvironmentLight> uniform_sky(float radiance) {
  return std::make_shared<EnvironmentLight>(cv::Mat(16, 32, CV_32FC3, cv::Scalar::all(radiance)));
}

PinholeCamera looking_down(int size, double height) {
  PinholeCamera cam;
  cam.width = cam.height = size;
  cam.fx = cam.fy = size;  // narrow view
  cam.cx = cam.cy = (size - 1) / 2.0;
  // Camera z toward world -Y, x toward +X, y toward +Z.
  cam.R_world_from_cam << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  cam.center_world = {0, height, 0};
  return cam;
}

// A Lambertian plane under a uniform white sky of radiance L reflects
// exactly albedo * L (the white furnace test).
TEST(PathTracer, DiffusePlaneUnderUniformSkyReflectsAlbedoTimesSky) {
  Scene scene;
  scene.add_mesh(floor_quad(1000.f, {0.5f, 0.25f, 0.75f}), Layer::Background);
  scene.commit();
  LightRig lights;
  lights.environment = std::make_shared<EnvironmentLight>(cv::Mat(16, 32, CV_32FC3, cv::Scalar::all(2.0)));
  RenderSettings settings;
  settings.samples_per_pixel = 64;
  settings.max_bounces = 1;
  const cv::Mat image = render_image(scene, looking_down(16, 1.0), lights, settings);
  const cv::Scalar mean = cv::mean(image);
  EXPECT_NEAR(mean[0], 1.0, 0.03);
  EXPECT_NEAR(mean[1], 0.5, 0.02);
  EXPECT_NEAR(mean[2], 1.5, 0.04);
}

// Irradiance from a small area light straight above: E = L*A/d^2, radiance = albedo/pi * E.
TEST(PathTracer, SmallAreaLightFollowsInverseSquareLaw) {
  Scene scene;
  scene.add_mesh(floor_quad(50.f, {1.f, 1.f, 1.f}), Layer::Background);
  scene.commit();
  LightRig lights;
  AreaLight light;
  light.corner = {-0.05f, 2.f, -0.05f};
  light.edge_u = {0.1f, 0, 0};
  light.edge_v = {0, 0, 0.1f};  // u x v = -Y: facing down
  light.radiance = Eigen::Vector3f::Constant(100.f);
  ASSERT_LT(light.normal().y(), 0.f);
  lights.area_lights.push_back(light);
  RenderSettings settings;
  settings.samples_per_pixel = 16;
  settings.max_bounces = 1;
  PinholeCamera cam = looking_down(8, 1.0);
  cam.fx = cam.fy = 800;  // look at a tiny patch right below the light
  const cv::Mat image = render_image(scene, cam, lights, settings);
  const double expected = 1.0 / std::numbers::pi * 100.0 * 0.01 / 4.0;
  EXPECT_NEAR(cv::mean(image)[0], expected, expected * 0.02);
}

TEST(PathTracer, SameSeedGivesIdenticalImages) {
  SyntheticRoomSpec spec;
  spec.width = 48;
  spec.height = 36;
  const SyntheticRoom room = make_synthetic_room(spec);
  Scene scene;
  scene.add_mesh(room.room, Layer::Background);
  scene.commit();
  RenderSettings settings;
  settings.samples_per_pixel = 2;
  const cv::Mat a = render_image(scene, room.camera, room.lights, settings);
  const cv::Mat b = render_image(scene, room.camera, room.lights, settings);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  EXPECT_TRUE(cv::checkRange(a));
  EXPECT_GT(cv::mean(a)[0], 0.01);
}

// Russian roulette ends only paths whose throughput has fallen below 0.1. In
// a closed box with no light every path bounces to the limit when the walls'
// albedo is 0.9 (0.9^5 > 0.1): exactly pixels x spp x (bounces + 1) closest-hit
// rays. With walls of albedo 0.2 (0.2^2 < 0.1) paths end early.
TEST(PathTracer, RouletteSparesPathsAboveATenthOfTheirThroughput) {
  constexpr int kSize = 8, kSpp = 4, kBounces = 5;
  const auto rays_in_box = [&](float albedo) {
    Mesh box;
    Material grey;
    grey.albedo = Eigen::Vector3f::Constant(albedo);
    box.materials.push_back(grey);
    add_box(box, {-1.f, 0.f, -1.f}, {1.f, 2.f, 1.f}, 0);
    add_quad(box, {-1.f, 0.f, 1.f}, {1.f, 0.f, 1.f}, {1.f, 0.f, -1.f}, {-1.f, 0.f, -1.f}, 0, 1.f);  // its floor
    Scene scene;
    scene.add_mesh(box, Layer::Background);
    scene.commit();
    RenderSettings settings;
    settings.samples_per_pixel = kSpp;
    settings.max_bounces = kBounces;
    RenderStats stats;
    const cv::Mat image = render_image(scene, looking_down(kSize, 1.0), LightRig{}, settings, &stats);
    EXPECT_EQ(cv::norm(image, cv::NORM_INF), 0.0);  // nothing lights it
    return stats.rays;
  };
  const uint64_t every_bounce = uint64_t{kSize} * kSize * kSpp * (kBounces + 1);
  EXPECT_EQ(rays_in_box(0.9f), every_bounce);
  EXPECT_LT(rays_in_box(0.2f), every_bounce * 3 / 4);
}

// Tolerances of the rendered analytic cases below (Monte Carlo noise at
// their sample counts plus the narrow camera's spread of angles).
constexpr double kRenderTolerance = 0.02;

std::unique_ptr<Scene> floor_scene(const Material& floor_material) {
  auto scene = std::make_unique<Scene>();
  scene->add_mesh(floor_quad(1000.f, floor_material), Layer::Background);
  scene->commit();
  return scene;
}

// A patch right under a camera looking down from 1 m with a narrow view.
PinholeCamera patch_camera() {
  PinholeCamera cam = looking_down(8, 1.0);
  cam.fx = cam.fy = 800;
  return cam;
}

// A white Lambertian floor lit by a sphere light straight above: E = pi L (r/d)^2,
// so the floor's radiance is E / pi = L (r/d)^2. Both light sampling and BSDF
// sampling (MIS) contribute.
TEST(PathTracer, SphereLightIrradianceOnALambertianFloor) {
  const auto scene = floor_scene(material(Material::Type::Diffuse, 1.f));
  LightRig lights;
  SphereLight bulb;
  bulb.center = {0.f, 2.f, 0.f};
  bulb.radius = 0.4f;
  bulb.radiance = Eigen::Vector3f::Constant(10.f);
  lights.sphere_lights.push_back(bulb);
  RenderSettings settings;
  settings.samples_per_pixel = 64;
  settings.max_bounces = 1;
  const cv::Mat image = render_image(*scene, patch_camera(), lights, settings);
  const double expected = 10.0 * std::pow(0.4 / 2.0, 2);
  EXPECT_NEAR(cv::mean(image)[0], expected, expected * kRenderTolerance);
}

// Sun at 30 degrees from the zenith: E = intensity cos(30), radiance E / pi.
TEST(PathTracer, SunIrradianceIsIntensityTimesCosine) {
  const auto scene = floor_scene(material(Material::Type::Diffuse, 1.f));
  LightRig lights;
  SunLight sun;
  const double t = std::numbers::pi / 6;
  sun.direction = Eigen::Vector3f(static_cast<float>(std::sin(t)), static_cast<float>(std::cos(t)), 0.f);
  sun.irradiance = Eigen::Vector3f(2.f, 1.f, 0.5f);
  lights.suns.push_back(sun);
  RenderSettings settings;
  settings.samples_per_pixel = 16;
  settings.max_bounces = 1;
  const cv::Mat image = render_image(*scene, patch_camera(), lights, settings);
  const cv::Scalar mean = cv::mean(image);
  for (int c = 0; c < 3; ++c) {
    const double expected = sun.irradiance[c] * std::cos(t) / std::numbers::pi;
    EXPECT_NEAR(mean[c], expected, expected * kRenderTolerance) << c;
  }
}

// A sun from outside a room shines only through its window: straight down
// through a 1 m square 2 m above the floor it lights that square of the
// floor, E / pi, and nothing beside it; with no window it reaches nothing.
TEST(PathTracer, ASunThroughAWindowLightsOnlyTheFloorBelowIt) {
  const auto scene = floor_scene(material(Material::Type::Diffuse, 1.f));
  PinholeCamera cam = looking_down(32, 4.0);
  cam.fx = cam.fy = 16;  // the floor from -4 to 4 m
  LightRig lights;
  SunLight sun;
  sun.irradiance = Eigen::Vector3f::Constant(3.f);
  sun.through_portals = true;
  lights.suns.push_back(sun);
  RenderSettings settings;
  settings.samples_per_pixel = 8;
  settings.max_bounces = 1;
  EXPECT_EQ(cv::norm(render_image(*scene, cam, lights, settings), cv::NORM_INF), 0.0);

  lights.portals.push_back({Eigen::Vector3f(0.f, 2.f, 0.f), Eigen::Vector3f(1.f, 0.f, 0.f), Eigen::Vector3f(0.f, 0.f, 1.f)});
  const cv::Mat image = render_image(*scene, cam, lights, settings);
  ASSERT_TRUE(cv::checkRange(image));
  int lit = 0, dark = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      // The floor point this pixel sees (x toward +X, y toward +Z).
      const double fx = (x - cam.cx) / cam.fx * 4.0, fz = (y - cam.cy) / cam.fy * 4.0;
      const double value = image.at<cv::Vec3f>(y, x)[0];
      const double margin = 0.2;  // a pixel's footprint is 0.25 m
      if (fx > margin && fx < 1 - margin && fz > margin && fz < 1 - margin) {
        EXPECT_NEAR(value, 3.0 / std::numbers::pi, 3.0 / std::numbers::pi * kRenderTolerance) << x << "," << y;
        ++lit;
      } else if (fx < -margin || fx > 1 + margin || fz < -margin || fz > 1 + margin) {
        EXPECT_EQ(value, 0.0) << x << "," << y;
        ++dark;
      }
    }
  EXPECT_GT(lit, 0);
  EXPECT_GT(dark, 0);
}

// A uniform sky through a window is, for the room, an area light of the
// sky's radiance filling it: the floor below receives the same irradiance.
TEST(PathTracer, TheSkyThroughAWindowIsAnAreaLightOfTheSkysRadiance) {
  const auto scene = floor_scene(material(Material::Type::Diffuse, 1.f));
  const Eigen::Vector3f corner(-0.6f, 2.f, -0.4f), edge_u(1.2f, 0.f, 0.f), edge_v(0.f, 0.f, 0.8f);
  LightRig through_window;
  through_window.environment = uniform_sky(2.f);
  through_window.environment->set_through_portals(true);
  through_window.portals.push_back({corner, edge_u, edge_v});
  LightRig area;
  AreaLight panel;
  panel.corner = corner;
  panel.edge_u = edge_u;  // edge_u x edge_v faces down, toward the floor
  panel.edge_v = edge_v;
  panel.radiance = Eigen::Vector3f::Constant(2.f);
  area.area_lights.push_back(panel);
  RenderSettings settings;
  settings.samples_per_pixel = 256;
  settings.max_bounces = 1;
  const double sky = cv::mean(render_image(*scene, patch_camera(), through_window, settings))[0];
  const double quad = cv::mean(render_image(*scene, patch_camera(), area, settings))[0];
  EXPECT_GT(quad, 0.1);
  EXPECT_NEAR(sky, quad, quad * 0.05);
  // The open sky would give 2 (the white furnace): the window lets in a part.
  EXPECT_LT(sky, 1.0);

  // Sampled through the window, the sky converges as the area light does:
  // at 16 spp its pixels stray from the converged floor no more than the
  // area light's (sampled over the whole sphere, about 200x as far).
  settings.samples_per_pixel = 16;
  const auto stray = [&](const LightRig& lights) {
    PinholeCamera wide = looking_down(32, 1.0);
    wide.fx = wide.fy = 64;
    const cv::Mat image = render_image(*scene, wide, lights, settings);
    RenderSettings converged = settings;
    converged.samples_per_pixel = 1024;
    static const cv::Mat reference = render_image(*scene, wide, area, converged);
    return cv::norm(image, reference, cv::NORM_L2) / std::sqrt(static_cast<double>(image.total()));
  };
  EXPECT_LT(stray(through_window), 1.5 * stray(area));
}

// A sun at the horizon (its disc partly below it) on every material: finite, tiny, never NaN.
TEST(PathTracer, GrazingSunStaysFinite) {
  for (const Material& m : {material(Material::Type::Diffuse, 1.f), material(Material::Type::Plastic, 0.f),
                            material(Material::Type::Metal, 0.f), material(Material::Type::Dielectric, 0.f),
                            material(Material::Type::Dielectric, 0.5f)}) {
    const auto scene = floor_scene(m);
    for (double elevation_deg : {0.1, 0.0, -0.1, 1e-4}) {
      LightRig lights;
      SunLight sun;
      const double e = elevation_deg * std::numbers::pi / 180.0;
      sun.direction = Eigen::Vector3f(static_cast<float>(std::cos(e)), static_cast<float>(std::sin(e)), 0.f);
      sun.irradiance = Eigen::Vector3f::Constant(100.f);
      lights.suns.push_back(sun);
      RenderSettings settings;
      settings.samples_per_pixel = 16;
      settings.max_bounces = 3;
      PinholeCamera cam = patch_camera();
      cam.fx = cam.fy = 4;  // wide: grazing views of the floor as well
      const cv::Mat image = render_image(*scene, cam, lights, settings);
      ASSERT_TRUE(cv::checkRange(image)) << to_string(m.type) << " at " << elevation_deg;
      double lo = 0, hi = 0;
      cv::minMaxLoc(image.reshape(1), &lo, &hi);
      EXPECT_GE(lo, 0.0);
      if (m.type == Material::Type::Diffuse) {
        // At most the whole disc at elevation + radius: E sin(e + r) / pi.
        const double bound = 100.0 * std::sin((std::max(elevation_deg, 0.0) + 0.3) * std::numbers::pi / 180.0);
        EXPECT_LE(cv::mean(image)[0], bound / std::numbers::pi);
      }
    }
  }
}

// Lights with no area, radius, direction or power add nothing and no NaN.
TEST(PathTracer, DegenerateLightsAreHarmless) {
  const auto scene = floor_scene(material(Material::Type::Plastic, 0.2f, {0.5f, 0.5f, 0.5f}));
  LightRig degenerate;
  AreaLight flat;
  flat.edge_v = Eigen::Vector3f::Zero();
  degenerate.area_lights.push_back(flat);
  AreaLight dark;
  dark.corner = {-1.f, 2.f, -1.f};
  dark.radiance = Eigen::Vector3f::Zero();
  degenerate.area_lights.push_back(dark);
  SphereLight point;
  point.center = {0.f, 1.f, 0.f};
  point.radius = 0.f;
  degenerate.sphere_lights.push_back(point);
  SunLight no_power;
  no_power.irradiance = Eigen::Vector3f::Zero();
  degenerate.suns.push_back(no_power);
  SunLight no_direction;
  no_direction.direction = Eigen::Vector3f::Zero();
  degenerate.suns.push_back(no_direction);
  degenerate.environment = uniform_sky(0.f);
  RenderSettings settings;
  settings.samples_per_pixel = 16;
  settings.max_bounces = 3;
  PinholeCamera cam = patch_camera();
  cam.fx = cam.fy = 4;
  const cv::Mat black = render_image(*scene, cam, degenerate, settings);
  ASSERT_TRUE(cv::checkRange(black));
  EXPECT_EQ(cv::norm(black, cv::NORM_INF), 0.0);

  // With a real light among them, the degenerate ones change nothing but the noise.
  LightRig good;
  SphereLight bulb;
  bulb.center = {0.f, 2.f, 0.f};
  bulb.radius = 0.3f;
  bulb.radiance = Eigen::Vector3f::Constant(5.f);
  good.sphere_lights.push_back(bulb);
  LightRig mixed = degenerate;
  mixed.sphere_lights.push_back(bulb);
  settings.samples_per_pixel = 64;
  const cv::Mat a = render_image(*scene, patch_camera(), good, settings);
  const cv::Mat b = render_image(*scene, patch_camera(), mixed, settings);
  ASSERT_TRUE(cv::checkRange(b));
  EXPECT_NEAR(cv::mean(b)[0], cv::mean(a)[0], cv::mean(a)[0] * kRenderTolerance);
}

TEST(PathTracer, EnvironmentWithInvalidTexelsRendersFinite) {
  const auto scene = floor_scene(material(Material::Type::Metal, 0.3f, {0.9f, 0.9f, 0.9f}));
  cv::Mat sky(16, 32, CV_32FC3, cv::Scalar::all(1.0));
  sky.at<cv::Vec3f>(2, 3) = {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(), -7.f};
  sky.row(5).setTo(cv::Scalar::all(-std::numeric_limits<float>::infinity()));
  LightRig lights;
  lights.environment = std::make_shared<EnvironmentLight>(sky);
  RenderSettings settings;
  settings.samples_per_pixel = 8;
  PinholeCamera cam = patch_camera();
  cam.fx = cam.fy = 4;
  const cv::Mat image = render_image(*scene, cam, lights, settings);
  EXPECT_TRUE(cv::checkRange(image));
  EXPECT_GT(cv::mean(image)[0], 0.1);
}

// White furnace per material: a plane under a uniform sky of radiance L
// reflects L times its directional albedo, which the BSDF's own samples
// estimate independently of the integrator (NEE + BSDF sampling + MIS).
TEST(PathTracer, FurnaceMatchesTheBsdfAlbedoForEveryOpaqueMaterial) {
  for (const Material& m : {material(Material::Type::Plastic, 0.3f, {0.8f, 0.4f, 0.2f}),
                            material(Material::Type::Plastic, 0.f, {1.f, 1.f, 1.f}),
                            material(Material::Type::Metal, 0.4f, {0.95f, 0.64f, 0.54f}),
                            material(Material::Type::Metal, 0.f, {0.9f, 0.6f, 0.3f})}) {
    const detail::Bsdf bsdf(m, m.albedo);
    detail::Rng rng(8, 8);
    Eigen::Vector3d expected = Eigen::Vector3d::Zero();
    constexpr int kAlbedoSamples = 100000;
    for (int i = 0; i < kAlbedoSamples; ++i) {
      detail::BsdfSample s;
      const float u0 = rng.uniform(), u1 = rng.uniform(), u2 = rng.uniform();
      if (bsdf.sample(Eigen::Vector3f::UnitZ(), u0, u1, u2, s)) expected += (s.f * (s.wi.z() / s.pdf)).cast<double>();
    }
    expected *= 2.0 / kAlbedoSamples;  // sky radiance 2
    const auto scene = floor_scene(m);
    LightRig lights;
    lights.environment = uniform_sky(2.f);
    RenderSettings settings;
    settings.samples_per_pixel = 64;
    settings.max_bounces = 1;
    const cv::Scalar mean = cv::mean(render_image(*scene, patch_camera(), lights, settings));
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(mean[c], expected[c], expected[c] * kRenderTolerance) << to_string(m.type) << " " << m.roughness;
  }
}

// A smooth-shaded sphere under a uniform sky of radiance L reflects albedo * L
// everywhere (it is convex: nothing else occludes it); a pixel it covers in
// part also sees the sky. Near the silhouette the interpolated normal of a
// triangle facing the camera can face away from it; such pixels must not go
// dark (the shading normal is turned toward the viewer).
TEST(PathTracer, SmoothShadedSphereHasNoDarkSilhouette) {
  constexpr float kAlbedo = 0.5f, kSky = 1.f;
  constexpr double kMaxDeficit = 0.05;  // no pixel more than 5% below the analytic value
  constexpr int kCoverageGrid = 8;      // sub-pixel rays per side for the coverage
  Mesh sphere = sphere_mesh({0.f, 0.f, 0.f}, 0.5f, material(Material::Type::Diffuse, 1.f, Eigen::Vector3f::Constant(kAlbedo)),
                            16, 32);
  sphere.compute_vertex_normals();
  Scene scene;
  scene.add_mesh(sphere, Layer::Background);
  scene.commit();
  LightRig lights;
  lights.environment = uniform_sky(kSky);
  RenderSettings settings;
  settings.samples_per_pixel = 256;
  settings.max_bounces = 1;
  PinholeCamera cam;
  cam.width = cam.height = 40;
  cam.fx = cam.fy = 70;  // the sphere fills most of the frame
  cam.cx = cam.cy = (cam.width - 1) / 2.0;
  cam.R_world_from_cam << 1, 0, 0, 0, -1, 0, 0, 0, -1;  // looking along -Z
  cam.center_world = {0, 0, 2.f};
  const cv::Mat image = render_image(scene, cam, lights, settings);
  double worst_ratio = 1e9;
  int covered_pixels = 0;
  for (int y = 0; y < image.rows; ++y)
    for (int x = 0; x < image.cols; ++x) {
      int hits = 0;
      for (int j = 0; j < kCoverageGrid; ++j)
        for (int i = 0; i < kCoverageGrid; ++i) {
          const Eigen::Vector3f dir =
              cam.ray_direction(x - 0.5 + (i + 0.5) / kCoverageGrid, y - 0.5 + (j + 0.5) / kCoverageGrid).cast<float>();
          RayHit hit;
          hits += scene.intersect(cam.center_world.cast<float>(), dir, std::numeric_limits<float>::infinity(), true, hit);
        }
      if (hits == 0) continue;
      ++covered_pixels;
      const double coverage = static_cast<double>(hits) / (kCoverageGrid * kCoverageGrid);
      const double expected = coverage * kAlbedo * kSky + (1.0 - coverage) * kSky;
      worst_ratio = std::min(worst_ratio, image.at<cv::Vec3f>(y, x)[1] / expected);
    }
  ASSERT_GT(covered_pixels, 400);
  EXPECT_GE(worst_ratio, 1.0 - kMaxDeficit);
}

// Smooth glass is lossless: a glass sphere in a white furnace disappears
// (entering, leaving and total internal reflection all conserve radiance).
TEST(PathTracer, GlassSphereVanishesInAWhiteFurnace) {
  Scene scene;
  scene.add_mesh(sphere_mesh({0.f, 0.f, 0.f}, 0.5f, material(Material::Type::Dielectric, 0.f)), Layer::Prop);
  scene.commit();
  LightRig lights;
  lights.environment = uniform_sky(1.f);
  RenderSettings settings;
  settings.samples_per_pixel = 64;
  settings.max_bounces = 32;
  PinholeCamera cam = looking_down(12, 2.0);
  cam.fx = cam.fy = 12;  // the sphere (radius 0.5 at 2 m) fills the view
  const cv::Mat image = render_image(scene, cam, lights, settings);
  EXPECT_TRUE(cv::checkRange(image));
  EXPECT_NEAR(cv::mean(image)[0], 1.0, kRenderTolerance);
  // Rough glass loses a little (single-scattering microfacets), never gains.
  Scene rough;
  rough.add_mesh(sphere_mesh({0.f, 0.f, 0.f}, 0.5f, material(Material::Type::Dielectric, 0.4f)), Layer::Prop);
  rough.commit();
  const double rough_mean = cv::mean(render_image(rough, cam, lights, settings))[0];
  EXPECT_LT(rough_mean, 1.0 + kRenderTolerance);
  EXPECT_GT(rough_mean, 0.8);
}

// A near-mirror sees an area light only through BSDF sampling (light samples
// almost never land in its lobe): MIS must hand it the whole contribution.
TEST(PathTracer, NearMirrorReflectsAnAreaLight) {
  const Eigen::Vector3f f0(0.9f, 0.6f, 0.3f);
  const auto scene = floor_scene(material(Material::Type::Metal, 0.f, f0));
  LightRig lights;
  AreaLight panel;
  panel.corner = {-20.f, 3.f, -20.f};
  panel.edge_u = {40.f, 0.f, 0.f};
  panel.edge_v = {0.f, 0.f, 40.f};  // u x v = -Y: facing down
  panel.radiance = Eigen::Vector3f::Ones();
  lights.area_lights.push_back(panel);
  RenderSettings settings;
  settings.samples_per_pixel = 16;
  settings.max_bounces = 1;
  const cv::Scalar mean = cv::mean(render_image(*scene, patch_camera(), lights, settings));
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c], f0[c], f0[c] * kRenderTolerance) << c;
}

// An emissive mesh without a light of its own lights the scene through BSDF
// sampling; one with a light just in front is counted once, through the light.
TEST(PathTracer, EmissiveMeshesLightTheSceneOnceWithOrWithoutARigLight) {
  Material lamp = material(Material::Type::Emissive, 1.f);
  lamp.emission = Eigen::Vector3f::Constant(4.f);
  Mesh panel = floor_quad(0.5f, lamp);
  panel.transform(Eigen::Affine3f(Eigen::Translation3f(0.f, 1.5f, 0.f)));
  Scene scene;
  scene.add_mesh(floor_quad(1000.f, material(Material::Type::Diffuse, 1.f)), Layer::Background);
  scene.add_mesh(panel, Layer::Background);
  scene.commit();
  AreaLight light;
  light.corner = {-0.5f, 1.5f - 3e-3f, -0.5f};
  light.edge_u = {1.f, 0.f, 0.f};
  light.edge_v = {0.f, 0.f, 1.f};
  light.radiance = lamp.emission;
  // Reference: the light alone in a scene without the panel.
  const auto floor_only = floor_scene(material(Material::Type::Diffuse, 1.f));
  LightRig with_light;
  with_light.area_lights.push_back(light);
  RenderSettings settings;
  settings.samples_per_pixel = 256;
  settings.max_bounces = 1;
  const double reference = cv::mean(render_image(*floor_only, patch_camera(), with_light, settings))[0];
  const double panel_and_light = cv::mean(render_image(scene, patch_camera(), with_light, settings))[0];
  const double panel_alone = cv::mean(render_image(scene, patch_camera(), LightRig{}, settings))[0];
  EXPECT_NEAR(panel_and_light, reference, reference * kRenderTolerance);
  EXPECT_NEAR(panel_alone, reference, reference * 0.05);  // BSDF sampling only: noisier
}

}  // namespace
}  // namespace propcam::render

namespace propcam::render {
namespace {

// One set of shared paths split by light gives what a render of each light
// alone gives (up to noise), and the layers sum to the full render's mean.
TEST(PathTracer, LightImagesFromSharedPathsMatchOneRenderPerLight) {
  Scene scene;
  Material grey;
  grey.albedo = {0.6f, 0.5f, 0.4f};
  scene.add_mesh(floor_quad(3.f, grey), Layer::Background);
  scene.add_mesh(sphere_mesh({0.2f, 0.3f, 0.f}, 0.3f, grey), Layer::Background);
  scene.commit();
  LightRig lights;
  AreaLight left, right;
  left.corner = {-1.5f, 1.5f, -0.25f};
  left.edge_u = {0.5f, 0.f, 0.f};
  left.edge_v = {0.f, 0.f, 0.5f};  // u x v points down
  left.radiance = {4.f, 4.f, 4.f};
  right = left;
  right.corner = {1.0f, 1.2f, -0.25f};
  right.radiance = {1.f, 2.f, 3.f};
  lights.area_lights = {left, right};
  lights.environment = std::make_shared<EnvironmentLight>(cv::Mat(16, 32, CV_32FC3, cv::Scalar(0.2, 0.3, 0.5)));
  RenderSettings settings;
  settings.samples_per_pixel = 64;
  settings.max_bounces = 2;
  const PinholeCamera camera = looking_down(24, 2.5);
  const std::vector<cv::Mat> layers = render_background_light_images(scene, camera, lights, settings);
  ASSERT_EQ(layers.size(), 3u);
  cv::Mat sum(camera.height, camera.width, CV_32FC3, cv::Scalar::all(0));
  for (int i = 0; i < lights.count(); ++i) {
    const cv::Mat alone = render_background_image(scene, camera, lights.only(i), settings);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(cv::mean(layers[i])[c] / cv::mean(alone)[c], 1.0, 0.03) << "light " << i << " channel " << c;
    EXPECT_TRUE(cv::checkRange(layers[i]));
    sum += layers[i];
  }
  const cv::Mat full = render_background_image(scene, camera, lights, settings);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(cv::mean(sum)[c] / cv::mean(full)[c], 1.0, 0.02);
  // Deterministic.
  const std::vector<cv::Mat> again = render_background_light_images(scene, camera, lights, settings);
  for (int i = 0; i < lights.count(); ++i) EXPECT_EQ(cv::norm(layers[i], again[i], cv::NORM_INF), 0.0);
}

// Point, spot and disc lights on a white Lambertian floor, rendered (light
// sampling, and for the disc MIS with BSDF sampling): the floor's radiance
// under a point 2 m up is I / (pi d^2); under a spot pointing down the same
// (cos 0 = 1), and 0 where its cone does not reach; under a disc of radiance
// L and radius r, facing down, L r^2 / (r^2 + d^2); under a spot sphere
// L (r/d)^2.
TEST(PathTracer, PointSpotAndDiscLightsOnALambertianFloor) {
  const auto scene = floor_scene(material(Material::Type::Diffuse, 1.f));
  RenderSettings settings;
  settings.samples_per_pixel = 64;
  settings.max_bounces = 1;
  const auto floor_radiance = [&](const LightRig& rig) { return cv::mean(render_image(*scene, patch_camera(), rig, settings))[0]; };
  const double pi = std::numbers::pi;
  SpotCone down;
  down.direction = -Eigen::Vector3f::UnitY();
  down.half_angle = pi / 6;
  down.blend = 0.2;
  SpotCone sideways = down;
  sideways.direction = Eigen::Vector3f::UnitX();

  LightRig point;
  point.point_lights.push_back({Eigen::Vector3f(0.f, 2.f, 0.f), Eigen::Vector3f::Constant(10.f), std::nullopt});
  const double point_expected = 10.0 / (pi * 4.0);
  EXPECT_NEAR(floor_radiance(point), point_expected, point_expected * kRenderTolerance);

  LightRig spot = point;
  spot.point_lights[0].spot = down;
  EXPECT_NEAR(floor_radiance(spot), point_expected, point_expected * kRenderTolerance);
  spot.point_lights[0].spot = sideways;
  EXPECT_EQ(floor_radiance(spot), 0.0);

  LightRig disc;
  DiscLight d;
  d.centre = {0.f, 2.f, 0.f};
  d.normal = -Eigen::Vector3f::UnitY();
  d.radius = 0.5f;
  d.radiance = Eigen::Vector3f::Constant(6.f);
  disc.disc_lights.push_back(d);
  const double disc_expected = 6.0 * 0.25 / (0.25 + 4.0);
  EXPECT_NEAR(floor_radiance(disc), disc_expected, disc_expected * kRenderTolerance);
  disc.disc_lights[0].normal = Eigen::Vector3f::UnitY();  // facing away: one-sided
  EXPECT_EQ(floor_radiance(disc), 0.0);

  LightRig sphere_spot;
  SphereLight bulb;
  bulb.center = {0.f, 2.f, 0.f};
  bulb.radius = 0.4f;
  bulb.radiance = Eigen::Vector3f::Constant(10.f);
  bulb.spot = down;
  sphere_spot.sphere_lights.push_back(bulb);
  const double sphere_expected = 10.0 * std::pow(0.4 / 2.0, 2);
  EXPECT_NEAR(floor_radiance(sphere_spot), sphere_expected, sphere_expected * kRenderTolerance);
  sphere_spot.sphere_lights[0].spot = sideways;
  EXPECT_EQ(floor_radiance(sphere_spot), 0.0);
}

// The per-light layers keep the rig order with the new kinds among the old
// (area, sphere, sun, disc, point, environment): each layer matches a render
// of LightRig::only(i).
TEST(PathTracer, LightImagesKeepTheRigOrderWithDiscsAndPoints) {
  Scene scene;
  Material grey;
  grey.albedo = {0.6f, 0.5f, 0.4f};
  scene.add_mesh(floor_quad(3.f, grey), Layer::Background);
  scene.add_mesh(sphere_mesh({0.2f, 0.3f, 0.f}, 0.3f, grey), Layer::Background);
  scene.commit();
  LightRig lights;
  AreaLight panel;
  panel.corner = {-1.5f, 1.5f, -0.25f};
  panel.edge_u = {0.5f, 0.f, 0.f};
  panel.edge_v = {0.f, 0.f, 0.5f};  // u x v points down
  panel.radiance = {4.f, 4.f, 4.f};
  lights.area_lights = {panel};
  SphereLight bulb;
  bulb.center = {-0.8f, 1.2f, 0.6f};
  bulb.radius = 0.1f;
  bulb.radiance = {30.f, 20.f, 10.f};
  bulb.spot = SpotCone{};
  lights.sphere_lights = {bulb};
  SunLight sun;
  sun.direction = {0.3f, 1.f, -0.2f};
  sun.irradiance = {0.5f, 0.5f, 0.5f};
  lights.suns = {sun};
  DiscLight disc;
  disc.centre = {1.f, 1.3f, 0.f};
  disc.radius = 0.3f;
  disc.radiance = {1.f, 3.f, 2.f};
  lights.disc_lights = {disc};
  PointLight point;
  point.position = {0.5f, 1.f, 0.8f};
  point.intensity = {1.f, 0.5f, 2.f};
  lights.point_lights = {point};
  lights.environment = std::make_shared<EnvironmentLight>(cv::Mat(16, 32, CV_32FC3, cv::Scalar(0.2, 0.3, 0.5)));
  RenderSettings settings;
  settings.samples_per_pixel = 32;
  settings.max_bounces = 2;
  const PinholeCamera camera = looking_down(16, 2.5);
  const std::vector<cv::Mat> layers = render_background_light_images(scene, camera, lights, settings);
  ASSERT_EQ(layers.size(), 6u);
  for (int i = 0; i < lights.count(); ++i) {
    const cv::Mat alone = render_background_image(scene, camera, lights.only(i), settings);
    EXPECT_TRUE(cv::checkRange(layers[i]));
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(cv::mean(layers[i])[c] / cv::mean(alone)[c], 1.0, 0.05) << "light " << i << " channel " << c;
  }
}

// A light hidden from the camera: the pixels that see it lose exactly its
// emission, every other pixel (its light on the floor, its reflection in a
// mirror) is bit-identical, as with Cycles' camera ray visibility.
TEST(PathTracer, CameraInvisibleLightsStillLightAndShowInReflections) {
  RenderSettings settings;
  settings.samples_per_pixel = 16;
  settings.max_bounces = 2;
  const PinholeCamera camera = looking_down(32, 3.0);  // x toward +X; tan of the half view 0.5
  SphereLight bulb;
  bulb.center = {0.6f, 1.f, 0.f};  // seen at x = 15.5 + 32 * 0.6 / 2 = 25.1 px, 1.6 px wide
  bulb.radius = 0.1f;
  bulb.radiance = Eigen::Vector3f::Constant(20.f);
  LightRig visible, hidden;
  visible.sphere_lights.push_back(bulb);
  bulb.visible_to_camera = false;
  hidden.sphere_lights.push_back(bulb);
  const cv::Rect bulb_pixels(22, 12, 7, 8);
  for (const Material& floor : {material(Material::Type::Diffuse, 1.f, Eigen::Vector3f::Constant(0.5f)),
                                material(Material::Type::Metal, 0.f, Eigen::Vector3f::Constant(0.9f))}) {
    SCOPED_TRACE(to_string(floor.type));
    const auto scene = floor_scene(floor);
    const cv::Mat seen = render_image(*scene, camera, visible, settings);
    const cv::Mat unseen = render_image(*scene, camera, hidden, settings);
    ASSERT_TRUE(cv::checkRange(unseen));
    // Where the camera looks straight at it: only what lies behind it.
    EXPECT_GT(seen.at<cv::Vec3f>(15, 25)[0], 10.f);
    EXPECT_LT(unseen.at<cv::Vec3f>(15, 25)[0], 1.f);
    // Everywhere else: the same image, bit for bit.
    cv::Mat elsewhere(seen.size(), CV_8U, cv::Scalar(255));
    elsewhere(bulb_pixels).setTo(0);
    EXPECT_EQ(cv::norm(seen, unseen, cv::NORM_INF, elsewhere), 0.0);
    if (floor.type == Material::Type::Metal) {
      // Its mirror image (at 4 m: x = 15.5 + 32 * 0.15 = 20.3 px) is still there.
      EXPECT_GT(unseen.at<cv::Vec3f>(15, 20)[0], 5.f);
    } else {
      // It lights the floor: about 0.5 L (r/h)^2 = 0.1 at its foot, less farther away.
      EXPECT_GT(unseen.at<cv::Vec3f>(15, 22)[0], 0.05f);
      EXPECT_GT(unseen.at<cv::Vec3f>(15, 22)[0], unseen.at<cv::Vec3f>(15, 10)[0]);
      EXPECT_GT(unseen.at<cv::Vec3f>(15, 10)[0], 0.f);
    }
  }
  // The environment hidden from a camera looking at the horizon: the sky goes
  // black, the floor it lights stays the same.
  PinholeCamera level = camera;
  level.R_world_from_cam << 1, 0, 0, 0, -1, 0, 0, 0, -1;  // looking along -Z, image y down
  level.center_world = {0, 1, 0};
  const auto scene = floor_scene(material(Material::Type::Diffuse, 1.f, Eigen::Vector3f::Constant(0.5f)));
  LightRig sky;
  sky.environment = uniform_sky(1.f);
  const cv::Mat with_sky = render_image(*scene, level, sky, settings);
  auto dark_sky = std::make_shared<EnvironmentLight>(*sky.environment);
  dark_sky->set_visible_to_camera(false);
  sky.environment = dark_sky;
  const cv::Mat without_sky = render_image(*scene, level, sky, settings);
  const cv::Rect above(0, 0, 32, 14), below(0, 18, 32, 14);
  EXPECT_EQ(cv::norm(without_sky(above), cv::NORM_INF), 0.0);
  EXPECT_GT(cv::mean(with_sky(above))[0], 0.9);
  EXPECT_EQ(cv::norm(with_sky(below), without_sky(below), cv::NORM_INF), 0.0);
  EXPECT_GT(cv::mean(without_sky(below))[0], 0.2);
}

}  // namespace
}  // namespace propcam::render
