// Depth of field as a post-process on the composite (the paper's
// post-process effects): a thin lens focused at a distance blurs each pixel
// by its circle of confusion, gathered so that a blurred foreground spreads
// over the background but a blurred background never bleeds over a sharp
// foreground.
#pragma once

#include <opencv2/core.hpp>

namespace propcam::render {

struct DepthOfField {
  double focus_distance_m = 2.0;   // depth (camera z) that stays sharp
  double aperture_m = 0.0;         // entrance pupil diameter; 0 is a pinhole (no blur)
  double max_blur_px = 24.0;       // circles of confusion are clamped to this diameter
};

// Circle-of-confusion diameter in pixels for depth z (thin lens, focus far
// beyond the focal length): fx * A * |1/z - 1/z_focus|.
double circle_of_confusion_px(double depth_m, double fx_px, const DepthOfField& dof);

// `linear` CV_32FC3, `depth` CV_32F metres along camera z (non-positive or
// non-finite depth counts as infinitely far). Returns a new image; the input
// is returned unchanged (cloned) when the aperture is 0.
cv::Mat apply_depth_of_field(const cv::Mat& linear, const cv::Mat& depth, double fx_px, const DepthOfField& dof);

}  // namespace propcam::render
