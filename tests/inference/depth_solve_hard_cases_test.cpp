#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "propcam/inference/depth_solve.h"
#include "propcam/render/depth_mesh.h"

namespace propcam::inference {
namespace {

render::PinholeCamera level_camera(int w, int h) {
  render::PinholeCamera c;
  c.width = w;
  c.height = h;
  c.fx = c.fy = 0.85 * std::max(w, h);
  c.cx = 0.5 * (w - 1);
  c.cy = 0.5 * (h - 1);
  c.center_world = Eigen::Vector3d(0, 1.5, 0);
  return c;
}

TEST(DepthSolveHardCases, NoTargetIsAClearError) {
  DepthProblem p;
  p.camera.width = 32;
  p.camera.height = 24;
  p.camera.fx = p.camera.fy = 30;
  p.camera.cx = 16;
  p.camera.cy = 12;
  EXPECT_THROW(solve_depth(p), std::invalid_argument);
  p.targets.push_back({cv::Mat(24, 32, CV_32F, cv::Scalar(-1.f)), 1.0, {}});
  EXPECT_THROW(solve_depth(p), std::invalid_argument);  // no opinion anywhere
}

TEST(DepthSolveHardCases, AllSkyNanTargetsAndTinyFrames) {
  for (int side : {1, 2, 16}) {
    DepthProblem p;
    p.camera.width = side;
    p.camera.height = side;
    p.camera.fx = p.camera.fy = side;
    p.camera.cx = p.camera.cy = 0.5 * (side - 1);
    cv::Mat target(side, side, CV_32F, cv::Scalar(3.f));
    if (side > 1) target.at<float>(0, 0) = std::nanf("");
    p.targets.push_back({target, 1.0, {}});
    const DepthSolution s = solve_depth(p);
    EXPECT_TRUE(cv::checkRange(s.depth)) << side;
    EXPECT_EQ(s.depth.size(), cv::Size(side, side));
    p.sky_mask = cv::Mat(side, side, CV_8U, cv::Scalar(255));
    const DepthSolution sky = solve_depth(p);
    EXPECT_FLOAT_EQ(sky.depth.at<float>(0, 0), static_cast<float>(render::kSkyDepthM));
    EXPECT_TRUE(cv::checkRange(sky.normals));
  }
}

TEST(DepthSolveHardCases, ExtremeTargetsStayBounded) {
  DepthProblem p;
  p.camera = level_camera(48, 36);
  cv::Mat wild(36, 48, CV_32F, cv::Scalar(4.f));
  wild.rowRange(0, 10).setTo(1e9f);
  wild.rowRange(10, 12).setTo(std::numeric_limits<float>::infinity());
  wild.rowRange(20, 22).setTo(1e-9f);
  p.targets.push_back({wild, 1.0, {}});
  const DepthSolution s = solve_depth(p);
  double lo = 0, hi = 0;
  cv::minMaxLoc(s.depth, &lo, &hi);
  EXPECT_GT(lo, 0.0);
  EXPECT_LT(hi, 1e4);
  EXPECT_TRUE(cv::checkRange(s.normals));
}

}  // namespace
}  // namespace propcam::inference
