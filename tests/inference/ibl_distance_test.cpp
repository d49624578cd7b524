#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "propcam/inference/ibl_distance.h"
#include "propcam/inference/ibl_library.h"

namespace propcam::inference {
namespace {

constexpr double kPi = 3.14159265358979323846;

TEST(IblDistance, UniformEnvironmentGivesPiTimesRadianceEverywhere) {
  const ShRadiance sh = project_radiance_sh(cv::Mat(64, 128, CV_32FC3, cv::Scalar(2, 2, 2)));
  for (const Eigen::Vector3d n : {Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 1, 0), Eigen::Vector3d(0.3, -0.5, 0.8)})
    EXPECT_NEAR(sh_irradiance(sh, n).x(), 2 * kPi, 0.01);
}

TEST(IblDistance, SunLightsTheSideFacingIt) {
  const cv::Mat sky = procedural_sky(40, 90, 3, 128);
  const ShRadiance sh = project_radiance_sh(sky);
  const Eigen::Vector3d sun = sun_direction(40, 90);
  EXPECT_GT(sh_irradiance(sh, sun).y(), 3 * sh_irradiance(sh, -sun).y());
}

TEST(IblDistance, IsZeroForTheSameLightUpToScaleAndGrowsWithTheSunsMove) {
  const ShRadiance a = project_radiance_sh(procedural_sky(40, 90, 3, 128));
  const ShRadiance a_bright = project_radiance_sh(procedural_sky(40, 90, 3, 128) * 7.0);
  const ShRadiance near = project_radiance_sh(procedural_sky(40, 110, 3, 128));
  const ShRadiance opposite = project_radiance_sh(procedural_sky(40, 270, 3, 128));
  EXPECT_NEAR(ibl_render_distance(a, a_bright), 0.0, 1e-6);  // the x7 is rounded in the float32 map
  EXPECT_DOUBLE_EQ(ibl_render_distance(a, near), ibl_render_distance(near, a));
  EXPECT_GT(ibl_render_distance(a, near), 0.0);
  EXPECT_GT(ibl_render_distance(a, opposite), 2 * ibl_render_distance(a, near));
}

TEST(IblDistance, BlackAndNonFiniteMapsStayFinite) {
  cv::Mat bad(32, 64, CV_32FC3, cv::Scalar(0, 0, 0));
  bad.at<cv::Vec3f>(3, 3) = cv::Vec3f(std::numeric_limits<float>::quiet_NaN(), -4.f,
                                      std::numeric_limits<float>::infinity());
  const ShRadiance black = project_radiance_sh(bad);
  EXPECT_TRUE(black.allFinite());
  EXPECT_EQ(black.norm(), 0.0);
  const ShRadiance sky = project_radiance_sh(procedural_sky(40, 90, 3, 64));
  EXPECT_TRUE(std::isfinite(ibl_render_distance(black, sky)));
  EXPECT_EQ(ibl_render_distance(black, black), 0.0);
  EXPECT_THROW(project_radiance_sh(cv::Mat()), std::invalid_argument);
}

}  // namespace
}  // namespace propcam::inference
