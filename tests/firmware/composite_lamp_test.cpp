// The lamp preset composited into a synthetic room: its light (prop_lights)
// must reach the photo's floor through differential rendering.
#include <gtest/gtest.h>

#include <cmath>

#include "common/compositor.h"
#include "propcam/render/props.h"
#include "worlds/synthetic_truth.h"

namespace propcam::firmware {
namespace {

TEST(CompositeLamp, TheLampBrightensTheFloorAroundIt) {
  render::SyntheticRoomSpec spec;
  spec.width = 96;
  spec.height = 72;
  spec.seed = 4;
  render::RenderSettings settings;
  settings.samples_per_pixel = 8;
  const SyntheticShot shot = shoot_synthetic_room(spec, settings);
  const Eigen::Vector2d px = free_floor_pixel(shot.room);
  const render::PropPlacement placement{px.x(), px.y(), 0.38, 20.0};
  settings.samples_per_pixel = 8;
  const CompositeResult lamp = composite_prop(shot.photo_linear, shot.truth, load_prop("lamp"), placement, settings);
  // The same lamp switched off: its shadow only.
  render::Mesh off = load_prop("lamp");
  for (auto& m : off.materials) m.emission.setZero();
  ASSERT_TRUE(render::prop_lights(off, Eigen::Affine3f::Identity()).empty());
  const CompositeResult unlit = composite_prop(shot.photo_linear, shot.truth, off, placement, settings);

  // The floor beside the lamp: pixels the prop does not cover, near its base.
  cv::Mat near(shot.photo_linear.size(), CV_8U, cv::Scalar(0));
  for (int y = 0; y < near.rows; ++y)
    for (int x = 0; x < near.cols; ++x) {
      const double r = std::hypot(x - px.x(), y - px.y());
      if (r > 2.0 && r < 10.0 && lamp.render.coverage.at<float>(y, x) == 0.f) near.at<uint8_t>(y, x) = 255;
    }
  ASSERT_GT(cv::countNonZero(near), 20);
  const double before = cv::mean(shot.photo_linear, near)[1];
  const double after = cv::mean(lamp.composite_linear, near)[1];
  const double switched_off = cv::mean(unlit.composite_linear, near)[1];
  EXPECT_GT(after, 1.1 * before) << after << " vs " << before;
  EXPECT_GT(after, 1.2 * switched_off) << after << " vs " << switched_off << " switched off";
  EXPECT_TRUE(cv::checkRange(lamp.composite_linear));
}

}  // namespace
}  // namespace propcam::firmware
