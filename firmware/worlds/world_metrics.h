// The errors `propcam bench worlds` reports per scene, each against a truth
// the world supplies: image similarity over a region (RMSE, SSIM), depth
// (abs-rel after median scaling), albedo (LMSE), the camera, the dominant
// light's direction and visible-light detection. Every function is finite
// and deterministic for any input; an empty region gives NaN, never a throw.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "propcam/inference/scene_model.h"
#include "propcam/render/camera.h"

namespace propcam::firmware {

// SSIM (Wang et al. 2004: 11x11 Gaussian window, sigma 1.5, K1 0.01, K2
// 0.03, dynamic range 1) of the Rec. 709 luma of two display-encoded images
// (CV_32FC3 in [0, 1]), averaged over the pixels of `mask` (CV_8U; empty:
// all). NaN for an empty mask.
double ssim_in_mask(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask);

// Depth error as monocular depth is scored: the estimate scaled by the
// median of truth/estimate over `valid` (CV_8U; pixels where both are
// finite, positive and below `max_depth_m`), then mean |s*est - true| / true.
double depth_abs_rel_median_scaled(const cv::Mat& estimate, const cv::Mat& truth, const cv::Mat& valid,
                                   double max_depth_m);

// Local mean squared error of albedo (Grosse et al. 2009): square windows of
// `window` pixels every window/2, each channel of each window scaled by its
// least-squares best factor, the summed squared error over the summed
// squared truth (so 0 is perfect and 1 is "predicted zero"). Pixels outside
// `valid` (CV_8U; empty: all) count as zero in both.
double albedo_lmse(const cv::Mat& estimate, const cv::Mat& truth, const cv::Mat& valid, int window);

// The camera against the truth: focal length |f/f_true - 1|; the angle
// between the two world "up" directions seen from the camera (tilt and roll
// together); pitch and roll errors (degrees); camera height |h/h_true - 1|.
struct CameraErrors {
  double focal_rel = 0, up_deg = 0, pitch_deg = 0, roll_deg = 0, height_rel = 0;
};
CameraErrors camera_errors(const render::PinholeCamera& estimate, const render::PinholeCamera& truth);

// Visible lights, object by object. The truth's emitters are the connected
// components of `truth` (CV_8U) covering at least `min_fraction` of the
// frame; smaller ones are "don't care". A true emitter is found when the
// estimate's mask (CV_8U) covers at least `min_cover` of it; a component
// of the estimate is right when at least half of it lies on a true emitter
// of any size (grown by `tolerance_px`), wrong when at least half lies off
// every emitter; the rest (on small emitters only) counts neither way.
struct EmitterCounts {
  int truth = 0, found = 0;      // recall = found / truth
  int detected = 0, right = 0;   // precision = right / detected
  EmitterCounts& operator+=(const EmitterCounts& o) {
    truth += o.truth, found += o.found, detected += o.detected, right += o.right;
    return *this;
  }
};
constexpr double kMinEmitterFraction = 1e-3;
EmitterCounts count_emitters(const cv::Mat& truth, const cv::Mat& estimate, double min_fraction = kMinEmitterFraction,
                             double min_cover = 0.1, int tolerance_px = 2);

// Angle between two directions (degrees); 180 when either is zero or not finite.
double angle_between_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

// The Khan-style baseline (Khan et al. 2006): `estimate`'s camera, geometry
// and albedo lit only by the photo wrapped onto a sphere, at its measured
// radiance (gamma 2.2, as the photo's display encoding).
inline constexpr int kKhanEnvironmentWidth = 128;
inference::SceneModel khan_baseline(const inference::SceneModel& estimate, const cv::Mat& photo_linear);

// What the scene-class stage saw, for a bench row: its report's details
// and the orientation map's ceiling and floor shares (null when absent).
nlohmann::json scene_class_cues(const std::vector<inference::StageReport>& reports);

}  // namespace propcam::firmware
