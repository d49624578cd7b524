#include <gtest/gtest.h>

#include "propcam/render/props.h"
#include "propcam/render/relight.h"
#include "propcam/render/render_session.h"
#include "propcam/render/synthetic_room.h"

namespace propcam::render {
namespace {

// Relighting must agree with rendering: the layers are exact per-light splits.
class RelightTest : public ::testing::Test {
 protected:
  void SetUp() override {
    SyntheticRoomSpec spec;
    spec.width = 64;
    spec.height = 48;
    spec.seed = 4;
    room_ = make_synthetic_room(spec);
    scene_.add_mesh(room_.room, Layer::Background);
    const Eigen::Affine3f at = Eigen::Translation3f(room_.free_floor_point) * Eigen::Scaling(0.6f);
    prop_ = scene_.add_prop(make_prop("cube"), at);
    scene_.commit();
    photo_ = cv::Mat(spec.height, spec.width, CV_32FC3, cv::Scalar(0.4, 0.4, 0.4));
    settings_.render.light_layers = true;
    settings_.render.max_bounces = 2;
    settings_.max_samples_per_pixel = 4;
    settings_.cull_tiles = false;
    ASSERT_GE(room_.lights.area_lights.size(), 1u);
  }

  cv::Mat render_with(const LightRig& lights, LightLayers* layers = nullptr) {
    RenderSession session(scene_, room_.camera, lights, photo_, scene_.world_bounds(prop_), settings_);
    while (!session.finished()) session.run_pass();
    if (layers) *layers = session.light_layers();
    return session.composite();
  }

  SyntheticRoom room_;
  Scene scene_;
  int prop_ = -1;
  cv::Mat photo_;
  SessionSettings settings_;
};

double max_abs_diff(const cv::Mat& a, const cv::Mat& b) { return cv::norm(a, b, cv::NORM_INF); }

TEST_F(RelightTest, UnitScalesGiveTheComposite) {
  LightLayers layers;
  const cv::Mat composite = render_with(room_.lights, &layers);
  EXPECT_EQ(layers.change.size(), static_cast<size_t>(room_.lights.count() + 1));
  EXPECT_LT(max_abs_diff(relight_prop(photo_, layers, {}), composite), 1e-4);
}

TEST_F(RelightTest, ScalingALayerEqualsRenderingWithTheLightScaled) {
  LightLayers layers;
  render_with(room_.lights, &layers);
  LightRig brighter = room_.lights;
  brighter.area_lights[0].radiance *= 2.f;
  const cv::Mat rendered = render_with(brighter);
  LightScales scales(layers.change.size(), 1.f);
  scales[0] = 2.f;
  const cv::Mat relit = relight_prop(photo_, layers, scales);
  cv::Mat diff;
  cv::absdiff(rendered, relit, diff);
  // Equal up to float rounding and the per-sample firefly clamps.
  EXPECT_LT(cv::mean(diff)[0], 1e-3);
  EXPECT_GT(max_abs_diff(relit, relight_prop(photo_, layers, {})), 1e-3) << "the light matters";
}

TEST_F(RelightTest, DarkLightsLeaveThePhotoAndABlackProp) {
  LightLayers layers;
  render_with(room_.lights, &layers);
  const cv::Mat dark = relight_prop(photo_, layers, LightScales(layers.change.size(), 0.f));
  for (int y = 0; y < dark.rows; ++y)
    for (int x = 0; x < dark.cols; ++x) {
      const float m = layers.coverage.at<float>(y, x);
      const cv::Vec3f expected = photo_.at<cv::Vec3f>(y, x) * (1.f - m);
      EXPECT_NEAR(dark.at<cv::Vec3f>(y, x)[1], expected[1], 1e-5);
    }
}

TEST_F(RelightTest, SceneRelightingScalesThePhotoByTheEmptySceneRatio) {
  LightLayers layers;
  const cv::Mat composite = render_with(room_.lights, &layers);
  RenderSettings s;
  s.samples_per_pixel = 4;
  const SceneLightLayers scene_layers = render_scene_light_layers(scene_, room_.camera, room_.lights, 16, s);
  ASSERT_EQ(scene_layers.empty_scene.size(), static_cast<size_t>(room_.lights.count()));
  EXPECT_LT(max_abs_diff(relight_scene(photo_, layers, scene_layers, {}), composite), 1e-4) << "unit scales: no change";
  const cv::Mat doubled = relight_scene(photo_, layers, scene_layers, LightScales(layers.change.size(), 2.f));
  // Far from the prop, every light doubled doubles the photo.
  EXPECT_NEAR(doubled.at<cv::Vec3f>(2, 2)[0], 2.f * photo_.at<cv::Vec3f>(2, 2)[0], 0.02);
}

TEST_F(RelightTest, BadScalesAndSizesAreClearErrors) {
  LightLayers layers;
  render_with(room_.lights, &layers);
  EXPECT_THROW(relight_prop(photo_, layers, {-1.f}), std::invalid_argument);
  EXPECT_THROW(relight_prop(photo_, layers, {std::numeric_limits<float>::quiet_NaN()}), std::invalid_argument);
  EXPECT_THROW(relight_prop(cv::Mat(4, 4, CV_32FC3), layers, {}), std::invalid_argument);
}

}  // namespace
}  // namespace propcam::render
