// Rec. 709 luminance of linear RGB, for the renderer's internal weights and
// error estimates (internal to render/).
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace propcam::render::detail {

inline float luminance(const Eigen::Vector3f& c) { return 0.2126f * c.x() + 0.7152f * c.y() + 0.0722f * c.z(); }
inline float luminance(const cv::Vec3f& c) { return 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2]; }

}  // namespace propcam::render::detail
