// Dense depth as the paper's energy (Karsch et al. 2014, eq. 2):
//   E(D) = sum_i E_t(D_i) + lm E_m(N(D)) + lo E_o(N(D)) + l3s E_3s(N(D))
// minimised with Ceres over log-depth at a reduced resolution, then
// upsampled edge-aware with the photo as guide.
//
// E_t, the data term: robust (soft-L1) distance of log D to each data target
//   (the depth-transfer median, the Manhattan box layout), per-pixel weighted.
// E_m, Manhattan: the normal's pairwise component products nx*ny, ny*nz,
//   nx*nz (world frame); all three vanish exactly when N is along an axis.
// E_o, orientation map: where the map labels a pixel with axis k, the normal's
//   two other components.
// E_3s, 3D smoothness: second differences of the back-projected 3D points
//   (relative to depth), robust (Cauchy) so creases and occlusion edges stay.
// Normals come from the 3D points of a pixel and its right and lower
// neighbours, so every prior is a function of three depths.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "propcam/inference/scene_model.h"
#include "propcam/render/camera.h"

namespace propcam::inference {

// The paper's weights (indoors 100, 0.5, 0.1; outdoors 200, 10, 1) belong to
// its own normalisation of each term. Ours are chosen the way it chose them, by
// a grid search on held-out generator scenes (`propcam bench geometry`; see
// docs/geometry.md).
struct DepthPriorWeights {
  double manhattan = 1.0;      // lambda_m
  double orientation = 0.1;    // lambda_o
  double smoothness = 10.0;    // lambda_3s
  static DepthPriorWeights indoor() { return {1.0, 0.1, 10.0}; }
  static DepthPriorWeights outdoor() { return {1.0, 0.1, 10.0}; }
};

struct DepthSolveOptions {
  int width = 60;               // solve grid width (height keeps the aspect ratio); see docs/geometry.md for the sweep
  int max_iterations = 20;      // Levenberg-Marquardt iterations (the sweep: 10 is nearly as good at half the time)
  // Wall-clock guard against a hang only: the iteration bound is what normally
  // stops the solve, so the result does not depend on the machine's load.
  double max_seconds = 5.0;
  DepthPriorWeights weights;
  bool use_manhattan = true;
  bool use_orientation = true;
  bool use_smoothness = true;
  // Soft-L1 scale of the data term in log-depth: residuals beyond ~10% count
  // linearly, so one wrong target cannot drag a whole region.
  double data_scale = 0.1;
  // Cauchy scale of the 3D second difference (relative to depth): larger
  // jumps are edges, not noise.
  double smoothness_scale = 0.05;
  double guide_sigma_color = 0.08;  // edge-aware upsampling: photo difference (sRGB) that halves the weight
  int num_threads = 2;
};

// One per-pixel depth hypothesis the data term pulls towards.
struct DepthTarget {
  cv::Mat depth;    // CV_32F metres, any size (resampled to the solve grid); <= 0 or non-finite: no opinion
  double weight = 1.0;
  cv::Mat confidence;  // optional CV_32F in [0,1], same size as depth
};

struct DepthProblem {
  render::PinholeCamera camera;   // full resolution, estimated
  std::vector<DepthTarget> targets;
  cv::Mat orientation_labels;     // optional CV_8U SurfaceOrientation (any size, nearest-resampled)
  cv::Mat sky_mask;               // optional CV_8U at camera size: fixed at kSkyDepthM, not solved
  cv::Mat guide_photo;            // optional linear CV_32FC3 at camera size: edge-aware upsampling guide
};

struct DepthSolution {
  cv::Mat depth;          // CV_32F metres at camera size (sky: kSkyDepthM)
  cv::Mat normals;        // CV_32FC3 world, at camera size
  cv::Mat depth_low;      // the solved grid itself
  StageReport report;     // stage "depth": final/initial cost, iterations, converged, solve size, seconds
};

// Throws std::invalid_argument when no target has an opinion anywhere or the
// sizes are inconsistent. Otherwise returns finite, positive depth.
DepthSolution solve_depth(const DepthProblem& problem, const DepthSolveOptions& options = {});

// World-frame normals of a depth map seen through `camera` (central
// differences; pixels without a valid neighbour keep the facing direction).
cv::Mat normals_from_depth(const cv::Mat& depth, const render::PinholeCamera& camera);

}  // namespace propcam::inference
