#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "propcam/render/path_tracer.h"
#include "propcam/render/synthetic_room.h"

namespace propcam::render {
namespace {

Mesh floor_quad(float half, const Eigen::Vector3f& albedo) {
  Mesh m;
  m.positions = {{-half, 0, -half}, {half, 0, -half}, {half, 0, half}, {-half, 0, half}};
  m.triangles = {{0, 2, 1}, {0, 3, 2}};
  m.material_ids = {0, 0};
  Material mat;
  mat.albedo = albedo;
  m.materials.push_back(mat);
  return m;
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

}  // namespace
}  // namespace propcam::render
