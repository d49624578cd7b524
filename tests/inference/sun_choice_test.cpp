// The street sun's choice (sun_choice.h): the candidate that lights what the
// measured sky alone cannot make so bright.
#include <gtest/gtest.h>

#include <functional>

#include "propcam/inference/sun_choice.h"

namespace propcam::inference {
namespace {

constexpr int kW = 40, kH = 20;
constexpr float kAlbedo = 0.5f;
constexpr float kSkyIrradiance = 0.1f;  // over pi, per unit albedo
constexpr float kSunIrradiance = 1.0f;

cv::Mat filled(float v) { return cv::Mat(kH, kW, CV_32FC3, cv::Scalar(v, v, v)); }

// A render (albedo x irradiance) lit where `lit` says.
cv::Mat sun_render(const std::function<bool(int x, int y)>& lit) {
  cv::Mat m = filled(0.f);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x)
      if (lit(x, y)) m.at<cv::Vec3f>(y, x) = cv::Vec3f::all(kAlbedo * kSunIrradiance);
  return m;
}

std::vector<cv::Point> all_pixels() {
  std::vector<cv::Point> p;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) p.push_back({x, y});
  return p;
}

struct Street {
  cv::Mat sky = filled(kAlbedo * kSkyIrradiance), albedo = filled(kAlbedo), photo;
  std::vector<cv::Mat> suns;
};

// The left half is sunlit in the photo: ten times what the sky gives it.
Street left_half_sunlit() {
  Street s;
  const cv::Mat truth = sun_render([](int x, int) { return x < kW / 2; });
  s.photo = s.sky + truth;
  s.suns = {sun_render([](int x, int) { return x >= kW / 2; }),  // the opposite side
            sun_render([](int, int) { return true; }),           // overhead: lights all
            truth};
  return s;
}

TEST(SunChoice, TheSunThatLightsWhatTheSkyCannotIsChosen) {
  const Street s = left_half_sunlit();
  const SunChoice c = choose_sun(s.suns, s.sky, s.albedo, s.photo, all_pixels());
  EXPECT_EQ(c.chosen, 2);
  EXPECT_EQ(c.must_be_sunlit, kW / 2 * kH);
  ASSERT_EQ(c.sunlit_share.size(), 3u);
  EXPECT_DOUBLE_EQ(c.sunlit_share[0], 0.0);
  EXPECT_DOUBLE_EQ(c.sunlit_share[1], 1.0);
  EXPECT_DOUBLE_EQ(c.sunlit_share[2], 1.0);
  // The overhead sun lights everything evenly: its shading says nothing.
  EXPECT_DOUBLE_EQ(c.agreement[1], 0.0);
  EXPECT_GT(c.agreement[2], 0.99);
}

// A wall facing the camera and brighter than the sky can make it (OpenCV's
// building.jpg). A sun behind the building lights only the wall's top edge,
// which is bright in the photo, so its shading correlates with the photo
// better than the sun behind the camera's, which lights everything evenly;
// but it leaves the bright wall unexplained, and the sun behind the camera
// is chosen.
TEST(SunChoice, ABacklitWallIsNotChosenForABrightWall) {
  Street s;
  const auto wall = [](int, int y) { return y < kH - 4; };
  s.photo = s.sky + sun_render([](int, int) { return true; });
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x)
      if (!wall(x, y)) s.photo.at<cv::Vec3f>(y, x) *= 0.3f;  // a dark lawn, also sunlit
  const cv::Mat behind_building = sun_render([](int, int y) { return y == 0; });
  const cv::Mat behind_camera = sun_render([](int, int) { return true; });
  s.suns = {behind_building, behind_camera};
  const SunChoice c = choose_sun(s.suns, s.sky, s.albedo, s.photo, all_pixels());
  EXPECT_EQ(c.chosen, 1);
  EXPECT_GT(c.agreement[0], c.agreement[1]);
  EXPECT_LT(c.sunlit_share[0], 0.1);
  EXPECT_DOUBLE_EQ(c.sunlit_share[1], 1.0);
}

}  // namespace
}  // namespace propcam::inference
