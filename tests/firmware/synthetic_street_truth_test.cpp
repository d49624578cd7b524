#include <gtest/gtest.h>

#include "propcam/render/depth_mesh.h"
#include "worlds/synthetic_truth.h"

namespace propcam::firmware {
namespace {

// The street's truth scene model: outdoor, sky pixels at kSkyDepthM with
// normals facing the camera, the ground plane, the sun as a Sun light.
TEST(SyntheticStreetTruth, SkyDepthGroundPlaneAndSun) {
  render::SyntheticStreetSpec spec;
  spec.width = 128;
  spec.height = 96;
  spec.seed = 3;  // looks down the street: sky above the horizon
  render::RenderSettings settings;
  settings.samples_per_pixel = 2;
  const SyntheticShot shot = shoot_synthetic_street(spec, settings);
  const inference::SceneModel& t = shot.truth;
  EXPECT_FALSE(t.indoor);
  ASSERT_EQ(t.depth.rows, 96);
  const render::PinholeCamera& cam = shot.room.camera;
  int sky = 0;
  for (int y = 0; y < t.height; ++y)
    for (int x = 0; x < t.width; ++x) {
      const float d = t.depth.at<float>(y, x);
      ASSERT_GT(d, 0.f);
      if (d != static_cast<float>(render::kSkyDepthM)) continue;
      ++sky;
      const Eigen::Vector3d ray = cam.ray_direction(x, y);
      EXPECT_GT(ray.y(), -0.02) << x << "," << y;  // sky is above the horizon (or at the street's far end)
      const cv::Vec3f n = t.normals.at<cv::Vec3f>(y, x);
      EXPECT_LT(Eigen::Vector3d(n[0], n[1], n[2]).dot(ray), -0.99);
    }
  EXPECT_GT(sky, t.width * t.height / 20);
  ASSERT_FALSE(t.planes.empty());
  EXPECT_NEAR(t.planes[0].normal.y(), 1.0, 1e-9);
  ASSERT_EQ(t.lights.size(), 2u) << "the sun and the sky";
  EXPECT_EQ(t.lights[0].type, inference::LightSource::Type::Sun);
  EXPECT_GT(t.lights[0].direction.y(), std::sin(10 * 3.14159265 / 180));
  EXPECT_EQ(t.lights[1].type, inference::LightSource::Type::Ibl);
  EXPECT_FALSE(t.lights[1].environment.empty());
  EXPECT_NEAR(shot.room.free_floor_point.y(), 0.f, 1e-6);
  EXPECT_FALSE(shot.photo_linear.empty());
}

}  // namespace
}  // namespace propcam::firmware
