#include <gtest/gtest.h>

#include "propcam/render/props.h"
#include "propcam/render/render_session.h"
#include "propcam/render/synthetic_room.h"
#include "propcam/render/transport_plan.h"

namespace propcam::render {
namespace {

Mesh prop_of(Material::Type type, float roughness, Eigen::Vector3f albedo) {
  Mesh m = make_prop("cube");
  for (auto& mat : m.materials) {
    mat.type = type;
    mat.roughness = roughness;
    mat.albedo = albedo;
  }
  return m;
}

AreaLight small_light_above(float size, float radiance) {
  AreaLight l;
  l.corner = {-size / 2, 2.5f, -size / 2};
  l.edge_u = {size, 0, 0};
  l.edge_v = {0, 0, size};
  if (l.normal().y() > 0) std::swap(l.edge_u, l.edge_v);  // face down
  l.radiance = Eigen::Vector3f::Constant(radiance);
  return l;
}

const TransportDecision& decision(const TransportPlan& plan, const std::string& effect) {
  for (const auto& d : plan.decisions)
    if (d.effect == effect) return d;
  throw std::runtime_error("no decision for " + effect);
}

struct PlanCase {
  Scene scene;
  LightRig lights;
  explicit PlanCase(const Mesh& prop) {
    scene.add_mesh(make_prop("cube"), Layer::Background);
    scene.add_prop(prop, Eigen::Affine3f(Eigen::Translation3f(0, 1, 0)));
    scene.commit();
  }
};

TEST(TransportPlan, ADiffusePropNeedsNoGlossyPathsAndNoCaustics) {
  PlanCase c(prop_of(Material::Type::Diffuse, 0.5f, {0.5f, 0.5f, 0.5f}));
  c.lights.area_lights.push_back(small_light_above(0.1f, 500.f));
  const TransportPlan plan = plan_transport(c.scene, c.lights, {});
  EXPECT_FALSE(decision(plan, "glossy").simulated);
  EXPECT_FALSE(decision(plan, "caustics").simulated);
  EXPECT_FALSE(plan.settings.caustics);
  EXPECT_TRUE(plan.settings.prop_interreflection) << "a mid-grey prop lights the floor visibly";
}

TEST(TransportPlan, ChromeUnderASmallStrongLightKeepsCaustics) {
  PlanCase c(prop_of(Material::Type::Metal, 0.05f, {0.9f, 0.9f, 0.9f}));
  c.lights.area_lights.push_back(small_light_above(0.1f, 500.f));
  const TransportPlan plan = plan_transport(c.scene, c.lights, {});
  EXPECT_TRUE(decision(plan, "caustics").simulated) << decision(plan, "caustics").why;
  EXPECT_TRUE(plan.settings.caustics);
  // The same chrome under a big soft sky only: no focusing light.
  PlanCase soft(prop_of(Material::Type::Metal, 0.05f, {0.9f, 0.9f, 0.9f}));
  soft.lights.environment = std::make_shared<EnvironmentLight>(cv::Mat(8, 16, CV_32FC3, cv::Scalar::all(1.0)));
  EXPECT_FALSE(plan_transport(soft.scene, soft.lights, {}).settings.caustics);
}

TEST(TransportPlan, ANearBlackPropsBounceLightIsSkipped) {
  PlanCase c(prop_of(Material::Type::Diffuse, 0.5f, {0.02f, 0.02f, 0.02f}));
  c.lights.area_lights.push_back(small_light_above(1.f, 10.f));
  EXPECT_FALSE(plan_transport(c.scene, c.lights, {}).settings.prop_interreflection);
}

TEST(TransportPlan, WeakLightsArePrunedAndTheirLayersComeBackEmpty) {
  PlanCase c(prop_of(Material::Type::Diffuse, 0.5f, {0.5f, 0.5f, 0.5f}));
  c.lights.area_lights.push_back(small_light_above(1.f, 10.f));
  c.lights.area_lights.push_back(small_light_above(0.01f, 1e-3f));  // negligible
  const TransportPlan plan = plan_transport(c.scene, c.lights, {});
  ASSERT_EQ(plan.lights.area_lights.size(), 1u);
  EXPECT_EQ(plan.source_index, std::vector<int>{0});
  LightLayers planned;
  planned.coverage = cv::Mat(2, 2, CV_32F, cv::Scalar(0));
  planned.change = {cv::Mat(2, 2, CV_32FC3, cv::Scalar::all(1)), cv::Mat(2, 2, CV_32FC3, cv::Scalar::all(3))};
  const LightLayers back = layers_in_original_order(plan, planned);
  ASSERT_EQ(back.change.size(), 3u);  // two rig lights and the emissive slot
  EXPECT_EQ(back.change[0].at<cv::Vec3f>(0, 0)[0], 1.f);
  EXPECT_EQ(back.change[1].at<cv::Vec3f>(0, 0)[0], 0.f);
  EXPECT_EQ(back.change[2].at<cv::Vec3f>(0, 0)[0], 3.f);
  PlanOptions everything;
  everything.allow_skips = false;
  EXPECT_EQ(plan_transport(c.scene, c.lights, {}, everything).lights.area_lights.size(), 2u);
}

// Without the prop's bounce light, a prop can only darken the photo.
TEST(TransportPlan, WithoutInterreflectionThePropOnlyDarkensThePhoto) {
  SyntheticRoomSpec spec;
  spec.width = 48;
  spec.height = 36;
  const SyntheticRoom room = make_synthetic_room(spec);
  Scene scene;
  scene.add_mesh(room.room, Layer::Background);
  scene.add_prop(prop_of(Material::Type::Diffuse, 0.5f, {0.9f, 0.9f, 0.9f}),
                 Eigen::Translation3f(room.free_floor_point) * Eigen::Scaling(0.5f));
  scene.commit();
  RenderSettings s;
  s.samples_per_pixel = 8;
  s.prop_interreflection = false;
  const DifferentialRender r = render_differential(scene, room.camera, room.lights, s);
  double max_gain = 0;
  for (int y = 0; y < r.change.rows; ++y)
    for (int x = 0; x < r.change.cols; ++x)
      if (r.coverage.at<float>(y, x) == 0.f) {
        const cv::Vec3f c = r.change.at<cv::Vec3f>(y, x);
        max_gain = std::max<double>(max_gain, std::max({c[0], c[1], c[2]}));
      }
  EXPECT_LE(max_gain, 1e-6);
  s.prop_interreflection = true;
  const DifferentialRender with_bounce = render_differential(scene, room.camera, room.lights, s);
  EXPECT_GT(cv::norm(with_bounce.change, r.change, cv::NORM_INF), 1e-4) << "the white prop does bounce light";
}

}  // namespace
}  // namespace propcam::render
