// Photos larger than the working size: the reduction and the composite
// carried back up to the photo's size.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "common/working_size.h"

namespace propcam::firmware {
namespace {

// A photo with detail finer than the working size can hold.
cv::Mat textured(int width, int height) {
  cv::Mat m(height, width, CV_32FC3);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      m.at<cv::Vec3f>(y, x) = cv::Vec3f(0.2f + 0.1f * ((x + y) % 2), 0.3f + 0.05f * (x % 3), 0.4f);
  return m;
}

TEST(WorkingSize, ReducesToTheBudgetKeepingTheAspect) {
  EXPECT_EQ(working_size({4000, 3000}, kDefaultWorkingPixels), cv::Size(1024, 768));
  EXPECT_EQ(working_size({640, 480}, kDefaultWorkingPixels), cv::Size(640, 480));
  EXPECT_EQ(working_size({11000, 11000}, kDefaultWorkingPixels), cv::Size(886, 886));
  const cv::Size strip = working_size({20000, 10}, 100);
  EXPECT_GE(strip.height, 1);
  EXPECT_LE(static_cast<long>(strip.width) * strip.height, 100);
  EXPECT_THROW(working_size({0, 10}, 100), std::invalid_argument);
}

// A textured photo worked at 50x38, and its composite: a red prop over the
// working pixels (20..25, 15..20), the rest of the photo untouched.
struct RedPropComposite {
  cv::Mat full, working, composite, coverage;
};
RedPropComposite red_prop_composite(cv::Size full_size) {
  RedPropComposite c;
  c.full = textured(full_size.width, full_size.height);
  c.working = reduce_to(c.full, {50, 38});
  c.composite = c.working.clone();
  c.coverage = cv::Mat(c.working.size(), CV_32F, cv::Scalar(0));
  c.composite(cv::Rect(20, 15, 6, 6)).setTo(cv::Scalar(0.9, 0.1, 0.1));
  c.coverage(cv::Rect(20, 15, 6, 6)).setTo(1.f);
  return c;
}

TEST(WorkingSize, WhatThePropLeftAloneStaysBitForBit) {
  const auto [full, working, composite, coverage] = red_prop_composite({200, 150});
  cv::Mat delivered = full.clone();
  deliver_at_full_size(delivered, working, composite, coverage);
  // Far from the prop (beyond one working pixel of interpolation) nothing moved.
  cv::Mat far_mask(full.size(), CV_8U, cv::Scalar(255));
  far_mask(cv::Rect(70, 50, 40, 40)).setTo(0);
  EXPECT_EQ(cv::norm(delivered, full, cv::NORM_INF, far_mask), 0.0);
  // Inside the prop: its colour.
  const cv::Vec3f inside = delivered.at<cv::Vec3f>(72, 92);
  EXPECT_NEAR(inside[0], 0.9f, 1e-4);
  EXPECT_NEAR(inside[1], 0.1f, 1e-4);
}

// Rendered at the full size, the prop's coverage puts its edge where it is,
// not smeared over the working pixel it crosses.
TEST(WorkingSize, ASharpCoverageGivesThePropItsFullSizeEdge) {
  const auto [full, working, composite, coverage] = red_prop_composite({200, 152});
  // Its edge at the full size: column 81, inside the working pixel 20 (80..83).
  SharpCoverage sharp;
  sharp.region = cv::Rect(70, 50, 40, 40);
  sharp.coverage = cv::Mat(sharp.region.size(), CV_32F, cv::Scalar(0));
  sharp.coverage(cv::Rect(81 - 70, 0, 22, 40)).setTo(1.f);

  cv::Mat soft = full.clone(), sharp_edge = full.clone();
  FullSizeDelivery(working, composite, coverage, full.size()).apply(soft, 0);
  FullSizeDelivery delivery(working, composite, coverage, full.size());
  delivery.use_sharp_coverage(sharp);
  delivery.apply(sharp_edge, 0);
  const int y = 70;
  EXPECT_NEAR(sharp_edge.at<cv::Vec3f>(y, 81)[0], 0.9f, 1e-4) << "the first column inside is the prop's";
  EXPECT_NEAR(sharp_edge.at<cv::Vec3f>(y, 80)[0], full.at<cv::Vec3f>(y, 80)[0], 1e-4) << "the last outside the photo's";
  EXPECT_GT(std::abs(soft.at<cv::Vec3f>(y, 80)[0] - full.at<cv::Vec3f>(y, 80)[0]), 0.05f) << "upsampled, it smears";
  // Outside the region the two agree.
  cv::Mat outside(full.size(), CV_8U, cv::Scalar(255));
  outside(sharp.region).setTo(0);
  EXPECT_EQ(cv::norm(soft, sharp_edge, cv::NORM_INF, outside), 0.0);

  SharpCoverage misplaced = sharp;
  misplaced.region.x = 180;
  EXPECT_THROW(delivery.use_sharp_coverage(misplaced), std::invalid_argument);
}

// A prop filling a 200 MP photo must not cost 1.8 G rays and 800 MB.
TEST(WorkingSize, TheRaysOfASharpCoverageAreBounded) {
  EXPECT_EQ(sharp_coverage_rays_per_side(230'000), 3);
  EXPECT_EQ(sharp_coverage_rays_per_side(4'000'000), 3);
  EXPECT_EQ(sharp_coverage_rays_per_side(9'000'000), 2);
  EXPECT_EQ(sharp_coverage_rays_per_side(16'000'000), 1);
  EXPECT_EQ(sharp_coverage_rays_per_side(16'000'001), 0);
  EXPECT_EQ(sharp_coverage_rays_per_side(200'000'000), 0);
  EXPECT_EQ(sharp_coverage_rays_per_side(0), 0);
  for (long pixels = 1; pixels <= kMaxSharpCoveragePixels; pixels *= 3) {
    const int n = sharp_coverage_rays_per_side(pixels);
    EXPECT_LE(static_cast<long long>(n) * n * pixels, kMaxSharpCoverageRays) << pixels;
  }
}

TEST(WorkingSize, AShadowDarkensTheFullPhotosOwnDetail) {
  const cv::Mat full = textured(200, 150);
  const cv::Mat working = reduce_to(full, {50, 38});
  cv::Mat composite = working.clone();
  composite(cv::Rect(10, 10, 20, 10)) *= 0.5;  // a shadow: half the light, no prop
  const cv::Mat coverage(working.size(), CV_32F, cv::Scalar(0));
  cv::Mat delivered = full.clone();
  deliver_at_full_size(delivered, working, composite, coverage);
  // Well inside the shadow every full pixel is halved, its texture kept.
  for (int y = 50; y < 70; ++y)
    for (int x = 50; x < 110; ++x)
      for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(delivered.at<cv::Vec3f>(y, x)[c], 0.5f * full.at<cv::Vec3f>(y, x)[c], 1e-3) << x << "," << y;
}

TEST(WorkingSize, BandsGiveWhatTheWholeImageGives) {
  const cv::Mat full = textured(97, 61);
  const cv::Mat working = reduce_to(full, {31, 19});
  cv::Mat composite = working * 0.8;
  cv::Mat coverage(working.size(), CV_32F, cv::Scalar(0));
  coverage(cv::Rect(10, 5, 5, 5)).setTo(0.5f);
  cv::Mat whole = full.clone();
  deliver_at_full_size(whole, working, composite, coverage);
  const FullSizeDelivery delivery(working, composite, coverage, full.size());
  cv::Mat banded = full.clone();
  for (int y = 0; y < full.rows; y += 7) {
    cv::Mat band = banded.rowRange(y, std::min(y + 7, full.rows));
    delivery.apply(band, y);
  }
  EXPECT_EQ(cv::norm(whole, banded, cv::NORM_INF), 0.0);
  EXPECT_TRUE(cv::checkRange(whole));
}

}  // namespace
}  // namespace propcam::firmware
