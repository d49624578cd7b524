#include <gtest/gtest.h>

#include <cmath>

#include "propcam/inference/scene_model.h"

namespace propcam::inference {
namespace {

TEST(SceneModel, LightRigHoldsEveryLightType) {
  std::vector<LightSource> lights(4);
  lights[0].type = LightSource::Type::Area;
  lights[0].edge_u = {1, 0, 0};
  lights[0].edge_v = {0, 0, 1};
  lights[1].type = LightSource::Type::Sun;
  lights[1].direction = {0.3, 1.0, -0.2};
  lights[1].intensity = {3.0, 2.9, 2.5};
  lights[2].type = LightSource::Type::Point;
  lights[2].position = {0.5, 2.0, -1.0};
  lights[2].intensity = {40, 40, 40};
  lights[3].type = LightSource::Type::Ibl;
  lights[3].environment = cv::Mat(8, 16, CV_32FC3, cv::Scalar(0.2, 0.2, 0.2));
  const render::LightRig rig = make_light_rig(lights);
  ASSERT_EQ(rig.area_lights.size(), 1u);
  ASSERT_EQ(rig.suns.size(), 1u);
  EXPECT_TRUE(rig.suns[0].emits());
  EXPECT_FLOAT_EQ(rig.suns[0].irradiance.x(), 3.0f);
  ASSERT_EQ(rig.sphere_lights.size(), 1u);
  EXPECT_TRUE(rig.sphere_lights[0].emits());
  EXPECT_FLOAT_EQ(rig.sphere_lights[0].center.y(), 2.0f);
  ASSERT_TRUE(rig.environment);
  EXPECT_EQ(rig.count(), 4);
  // Unit intensity (basis renders): every light at one.
  const render::LightRig unit = make_light_rig(lights, true);
  EXPECT_FLOAT_EQ(unit.suns[0].irradiance.y(), 1.0f);
}

TEST(SceneModel, DistantLightsGiveADirectionAndRoomLightsNone) {
  const Eigen::Vector3d camera(1, 1.5, -2);
  LightSource sun;
  sun.type = LightSource::Type::Sun;
  sun.direction = Eigen::Vector3d(0, 2, 0);
  ASSERT_TRUE(distant_light_direction(sun, camera));
  EXPECT_TRUE(distant_light_direction(sun, camera)->isApprox(Eigen::Vector3d::UnitY()));
  sun.direction = Eigen::Vector3d::Zero();
  EXPECT_FALSE(distant_light_direction(sun, camera)) << "a sun with no direction";

  LightSource sky_patch;  // a sky patch 1 km out, as the lighting places them
  sky_patch.type = LightSource::Type::Area;
  sky_patch.position = camera + 1000.0 * Eigen::Vector3d(0.6, 0.8, 0);
  ASSERT_TRUE(distant_light_direction(sky_patch, camera));
  EXPECT_TRUE(distant_light_direction(sky_patch, camera)->isApprox(Eigen::Vector3d(0.6, 0.8, 0)));

  LightSource lamp = sky_patch;  // a ceiling panel of the room
  lamp.position = camera + Eigen::Vector3d(0, 1.2, 2);
  EXPECT_FALSE(distant_light_direction(lamp, camera));
  lamp.position = Eigen::Vector3d::Constant(std::nan(""));
  EXPECT_FALSE(distant_light_direction(lamp, camera)) << "a non-finite position is no direction";
  LightSource point = sky_patch;
  point.type = LightSource::Type::Point;
  EXPECT_FALSE(distant_light_direction(point, camera)) << "only suns and area lights stand for distant light";
}

TEST(SceneModel, ADistantLightsIrradianceIsItsRadianceTimesItsSolidAngle) {
  const Eigen::Vector3d camera(1, 1.5, -2);
  LightSource sun;
  sun.type = LightSource::Type::Sun;
  sun.direction = Eigen::Vector3d(0, 1, 0);
  sun.intensity = Eigen::Vector3d(3, 2, 1);
  ASSERT_TRUE(distant_light_irradiance(sun, camera));
  EXPECT_TRUE(distant_light_irradiance(sun, camera)->isApprox(Eigen::Vector3d(3, 2, 1)));

  LightSource patch;  // 10 m square, 1 km out: 1e-4 sr
  patch.type = LightSource::Type::Area;
  patch.position = camera + Eigen::Vector3d(0, 1000, 0);
  patch.edge_u = Eigen::Vector3d(10, 0, 0);
  patch.edge_v = Eigen::Vector3d(0, 0, 10);
  patch.intensity = Eigen::Vector3d(2e4, 1e4, 0);
  ASSERT_TRUE(distant_light_irradiance(patch, camera));
  EXPECT_TRUE(distant_light_irradiance(patch, camera)->isApprox(Eigen::Vector3d(2, 1, 0)));

  LightSource lamp = patch;  // in the room: no irradiance from afar
  lamp.position = camera + Eigen::Vector3d(0, 1.2, 2);
  EXPECT_FALSE(distant_light_irradiance(lamp, camera));
}

}  // namespace
}  // namespace propcam::inference
