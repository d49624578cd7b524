#include <gtest/gtest.h>

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

}  // namespace
}  // namespace propcam::inference
