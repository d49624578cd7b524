// The sun search's hard cases: nothing to find gives found == false with
// finite numbers, the same each time.
#include "propcam/inference/sun_from_shadows.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "sun_street_scene.h"

namespace propcam::inference {
namespace {

using namespace propcam::inference::testing;

TEST(SunFromShadowsHardCases, NoShadowCastersNoSun) {
  // Bare ground: every sun lights it alike, so shadows cannot say where the sun is.
  const auto s = make_street(sun_at(40, 30), kSunIrradiance, false);
  const SunFromShadows found = sun_from_shadows(s->scene, s->camera, s->photo, s->albedo, s->sky_basis, s->usable);
  EXPECT_FALSE(found.found);
  EXPECT_TRUE(std::isfinite(found.variance_no_sun));
}

// A sun 2 degrees above the horizon behind the blocks: its light reaches the
// camera's view only at a grazing angle, adding under 3% of the photo's mean,
// too little to tell from the sky's own variation, so none is found. (A sun
// at 20 degrees there lights a third of the view, and is found.)
TEST(SunFromShadowsHardCases, AGrazingSunBehindTheBlocksIsNotFound) {
  constexpr double kMaxSunShare = 0.03;
  const auto s = make_street(sun_at(2, 170), kSunIrradiance);
  const auto without_sun = make_street(sun_at(2, 170), 0.0);
  ASSERT_LT(cv::mean(s->photo - without_sun->photo)[1], kMaxSunShare * cv::mean(s->photo)[1]) << "the premise";
  const SunFromShadows found = sun_from_shadows(s->scene, s->camera, s->photo, s->albedo, s->sky_basis, s->usable);
  EXPECT_FALSE(found.found);
  EXPECT_TRUE(std::isfinite(found.variance));
}

TEST(SunFromShadowsHardCases, OvercastNoSun) {
  const auto s = make_street(sun_at(40, 30), 0.0);
  const SunFromShadows found = sun_from_shadows(s->scene, s->camera, s->photo, s->albedo, s->sky_basis, s->usable);
  EXPECT_FALSE(found.found);
}

TEST(SunFromShadowsHardCases, BlackPhotoEmptyMaskAndBadSizes) {
  const auto s = make_street(sun_at(40, 30), kSunIrradiance);
  const cv::Mat black = cv::Mat::zeros(s->photo.size(), CV_32FC3);
  const SunFromShadows a = sun_from_shadows(s->scene, s->camera, black, s->albedo, s->sky_basis, s->usable);
  const SunFromShadows b = sun_from_shadows(s->scene, s->camera, black, s->albedo, s->sky_basis, s->usable);
  EXPECT_FALSE(a.found);
  EXPECT_TRUE(std::isfinite(a.variance_no_sun));
  EXPECT_EQ(a.variance, b.variance);
  const cv::Mat none = cv::Mat::zeros(s->usable.size(), CV_8U);
  EXPECT_FALSE(sun_from_shadows(s->scene, s->camera, s->photo, s->albedo, s->sky_basis, none).found);
  cv::Mat small;
  cv::resize(s->photo, small, {80, 60});
  EXPECT_FALSE(sun_from_shadows(s->scene, s->camera, small, s->albedo, s->sky_basis, s->usable).found);
  SunFromShadowsOptions bad;
  bad.ratio_steps = 0;
  EXPECT_FALSE(sun_from_shadows(s->scene, s->camera, s->photo, s->albedo, s->sky_basis, s->usable, bad).found);
}

TEST(SunFromShadowsHardCases, Deterministic) {
  const auto s = make_street(sun_at(30, 120), kSunIrradiance);
  const SunFromShadows a = sun_from_shadows(s->scene, s->camera, s->photo, s->albedo, s->sky_basis, s->usable);
  const SunFromShadows b = sun_from_shadows(s->scene, s->camera, s->photo, s->albedo, s->sky_basis, s->usable);
  EXPECT_EQ(a.direction, b.direction);
  EXPECT_EQ(a.irradiance_per_sky, b.irradiance_per_sky);
  EXPECT_EQ(a.variance, b.variance);
}

}  // namespace
}  // namespace propcam::inference
