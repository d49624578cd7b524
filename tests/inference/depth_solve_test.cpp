#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <opencv2/imgproc.hpp>

#include "propcam/inference/depth_solve.h"
#include "propcam/render/depth_mesh.h"
#include "room_truth.h"

namespace propcam::inference {
namespace {

double abs_rel(const cv::Mat& est, const cv::Mat& truth) {
  double s = 0;
  int n = 0;
  for (int y = 0; y < truth.rows; ++y)
    for (int x = 0; x < truth.cols; ++x) {
      const float t = truth.at<float>(y, x);
      if (t <= 0) continue;
      s += std::abs(est.at<float>(y, x) - t) / t;
      ++n;
    }
  return n ? s / n : 0;
}

double median_normal_error_deg(const cv::Mat& est, const cv::Mat& truth) {
  std::vector<double> e;
  for (int y = 1; y + 1 < truth.rows; ++y)
    for (int x = 1; x + 1 < truth.cols; ++x) {
      const cv::Vec3f a = est.at<cv::Vec3f>(y, x), b = truth.at<cv::Vec3f>(y, x);
      e.push_back(std::acos(std::clamp(static_cast<double>(a.dot(b)), -1.0, 1.0)) * 180.0 / M_PI);
    }
  std::nth_element(e.begin(), e.begin() + e.size() / 2, e.end());
  return e[e.size() / 2];
}

// What a data term looks like: right on average, blurred across edges and
// slightly noisy.
cv::Mat blurred_with_noise(const cv::Mat& depth, double sigma, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0.0, sigma);
  cv::Mat out;
  cv::log(depth, out);
  cv::blur(out, out, cv::Size(15, 15));
  cv::exp(out, out);
  for (int y = 0; y < out.rows; ++y)
    for (int x = 0; x < out.cols; ++x) out.at<float>(y, x) *= static_cast<float>(std::exp(n(rng)));
  return out;
}

TEST(DepthSolve, GeometricPriorsFlattenANoisyRoom) {
  const RoomTruth t = room_truth(2, 160, 120);
  DepthProblem p;
  p.camera = t.room.camera;
  p.targets.push_back({blurred_with_noise(t.depth, 0.03, 3), 1.0, {}});
  DepthSolveOptions o;
  o.width = 80;
  const DepthSolution s = solve_depth(p, o);
  ASSERT_TRUE(cv::checkRange(s.depth));
  const double noisy_normals = median_normal_error_deg(normals_from_depth(p.targets[0].depth, t.room.camera), t.normals);
  const double solved_normals = median_normal_error_deg(s.normals, t.normals);
  EXPECT_LT(solved_normals, 0.25 * noisy_normals) << noisy_normals << " -> " << solved_normals;
  EXPECT_LT(abs_rel(s.depth, t.depth), abs_rel(p.targets[0].depth, t.depth));
  EXPECT_LT(s.report.details["final_cost"].get<double>(), s.report.details["initial_cost"].get<double>());
  EXPECT_EQ(s.report.stage, "depth");
  EXPECT_TRUE(s.report.details.contains("converged"));
  EXPECT_LE(s.report.iterations, o.max_iterations + 1);
}

TEST(DepthSolve, OrientationLabelsTurnATiltedPlaneLevel) {
  // A floor target tilted by a few degrees, labelled as horizontal
  // everywhere: the orientation term levels it.
  const RoomTruth t = room_truth(4, 96, 72);
  DepthProblem p;
  p.camera = t.room.camera;
  const int w = p.camera.width, h = p.camera.height;
  cv::Mat floor_depth(h, w, CV_32F, 0.f);
  const double cam_h = t.room.camera.center_world.y();
  const Eigen::Vector3d tilted_up = Eigen::AngleAxisd(0.08, Eigen::Vector3d::UnitZ()) * Eigen::Vector3d::UnitY();
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const Eigen::Vector3d d = t.room.camera.ray_direction(x, y);
      const double along = -d.dot(tilted_up);
      if (along > 0.05) {
        const Eigen::Vector3d fwd = t.room.camera.R_world_from_cam.col(2);
        floor_depth.at<float>(y, x) = static_cast<float>(cam_h / along * d.dot(fwd));
      }
    }
  cv::Mat labels(h, w, CV_8U, cv::Scalar(2));  // kNormalY
  p.targets.push_back({floor_depth, 1.0, {}});
  p.orientation_labels = labels;
  DepthSolveOptions o;
  o.width = 48;
  o.use_manhattan = false;
  o.use_smoothness = false;
  o.weights.orientation = 50.0;
  const DepthSolution s = solve_depth(p, o);
  // Normals of the floor part point up after the solve.
  double up_sum = 0;
  int n = 0;
  for (int y = h / 2 + 4; y < h - 2; ++y)
    for (int x = 2; x < w - 2; ++x) {
      if (floor_depth.at<float>(y, x) <= 0) continue;
      up_sum += std::abs(s.normals.at<cv::Vec3f>(y, x)[1]);
      ++n;
    }
  ASSERT_GT(n, 0);
  EXPECT_GT(up_sum / n, std::cos(0.04));
}

TEST(DepthSolve, IsDeterministic) {
  const RoomTruth t = room_truth(1, 64, 48);
  DepthProblem p;
  p.camera = t.room.camera;
  p.targets.push_back({blurred_with_noise(t.depth, 0.03, 5), 1.0, {}});
  DepthSolveOptions o;
  o.width = 32;
  o.num_threads = 2;
  const DepthSolution a = solve_depth(p, o), b = solve_depth(p, o);
  EXPECT_EQ(cv::norm(a.depth, b.depth, cv::NORM_INF), 0.0);
}

}  // namespace
}  // namespace propcam::inference
