// Degenerate inputs to the street sun's choice (sun_choice.h): a chosen
// index in range (or -1 for no candidates), finite scores, the same twice.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "propcam/inference/sun_choice.h"

namespace propcam::inference {
namespace {

constexpr int kW = 16, kH = 12;
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

cv::Mat filled(float v) { return cv::Mat(kH, kW, CV_32FC3, cv::Scalar(v, v, v)); }

std::vector<cv::Point> all_pixels() {
  std::vector<cv::Point> p;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) p.push_back({x, y});
  return p;
}

void expect_sane(const SunChoice& c, size_t candidates) {
  ASSERT_EQ(c.sunlit_share.size(), candidates);
  ASSERT_EQ(c.agreement.size(), candidates);
  EXPECT_GE(c.chosen, 0);
  EXPECT_LT(c.chosen, static_cast<int>(candidates));
  for (size_t i = 0; i < candidates; ++i) {
    EXPECT_TRUE(std::isfinite(c.sunlit_share[i])) << i;
    EXPECT_TRUE(std::isfinite(c.agreement[i])) << i;
    EXPECT_GE(c.sunlit_share[i], 0.0);
    EXPECT_LE(c.sunlit_share[i], 1.0);
  }
  EXPECT_GE(c.must_be_sunlit, 0);
}

TEST(SunChoiceHardCases, NoCandidatesChoosesNone) {
  const SunChoice c = choose_sun({}, filled(0.1f), filled(0.5f), filled(0.2f), all_pixels());
  EXPECT_EQ(c.chosen, -1);
  EXPECT_TRUE(c.sunlit_share.empty());
}

TEST(SunChoiceHardCases, AnOvercastStreetLetsTheShadingChoose) {
  // Nothing brighter than the sky can make it: no pixel must be sunlit.
  const cv::Mat sky = filled(0.05f), albedo = filled(0.5f);
  cv::Mat photo = sky.clone(), lit_left = filled(0.f);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW / 2; ++x) photo.at<cv::Vec3f>(y, x) *= 1.5f, lit_left.at<cv::Vec3f>(y, x) = cv::Vec3f::all(0.5f);
  const SunChoice c = choose_sun({filled(0.5f), lit_left}, sky, albedo, photo, all_pixels());
  expect_sane(c, 2);
  EXPECT_EQ(c.must_be_sunlit, 0);
  EXPECT_EQ(c.chosen, 1);
}

TEST(SunChoiceHardCases, BlackPhotoOrBlackRendersStayFinite) {
  const std::vector<cv::Mat> suns = {filled(0.f), filled(0.5f)};
  expect_sane(choose_sun(suns, filled(0.1f), filled(0.5f), filled(0.f), all_pixels()), 2);
  expect_sane(choose_sun(suns, filled(0.f), filled(0.5f), filled(0.3f), all_pixels()), 2);  // the sky reaches nothing
  expect_sane(choose_sun(suns, filled(0.1f), filled(0.f), filled(0.3f), all_pixels()), 2);  // black albedo
}

TEST(SunChoiceHardCases, NonFiniteTexelsAreSkipped) {
  cv::Mat photo = filled(0.3f), sun = filled(0.5f), sky = filled(0.1f);
  photo.at<cv::Vec3f>(0, 0) = cv::Vec3f::all(kNaN);
  photo.at<cv::Vec3f>(1, 1) = cv::Vec3f::all(kInf);
  sun.at<cv::Vec3f>(2, 2) = cv::Vec3f::all(kNaN);
  sky.at<cv::Vec3f>(3, 3) = cv::Vec3f::all(kInf);
  expect_sane(choose_sun({sun, filled(0.2f)}, sky, filled(0.5f), photo, all_pixels()), 2);
}

TEST(SunChoiceHardCases, MismatchedSizesOrNoPixelsFallBackToTheFirst) {
  const std::vector<cv::Mat> suns = {filled(0.5f), filled(0.2f)};
  const SunChoice wrong_size = choose_sun(suns, cv::Mat(3, 3, CV_32FC3, cv::Scalar::all(0.1)), filled(0.5f), filled(0.3f), all_pixels());
  EXPECT_EQ(wrong_size.chosen, 0);
  expect_sane(choose_sun(suns, filled(0.1f), filled(0.5f), filled(0.3f), {}), 2);
  // Pixels outside the image are ignored.
  expect_sane(choose_sun(suns, filled(0.1f), filled(0.5f), filled(0.3f), {{-1, 0}, {kW, kH}, {2, 2}}), 2);
  // A candidate of the wrong size scores nothing and is never a crash.
  expect_sane(choose_sun({filled(0.5f), cv::Mat(2, 2, CV_32FC3)}, filled(0.1f), filled(0.5f), filled(0.3f), all_pixels()), 2);
}

TEST(SunChoiceHardCases, Deterministic) {
  cv::Mat photo = filled(0.3f), sun = filled(0.f);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      photo.at<cv::Vec3f>(y, x) = cv::Vec3f::all(0.1f + 0.05f * ((x * 7 + y * 3) % 11));
      sun.at<cv::Vec3f>(y, x) = cv::Vec3f::all(0.5f * ((x + y) % 3 == 0));
    }
  const std::vector<cv::Mat> suns = {sun, filled(0.5f), filled(0.1f)};
  const SunChoice a = choose_sun(suns, filled(0.05f), filled(0.5f), photo, all_pixels());
  const SunChoice b = choose_sun(suns, filled(0.05f), filled(0.5f), photo, all_pixels());
  expect_sane(a, 3);
  EXPECT_EQ(a.chosen, b.chosen);
  EXPECT_EQ(a.must_be_sunlit, b.must_be_sunlit);
  EXPECT_EQ(a.sunlit_share, b.sunlit_share);
  EXPECT_EQ(a.agreement, b.agreement);
}

}  // namespace
}  // namespace propcam::inference
