// Rec. 709 luminance of linear RGB: the one weighting the inference stages
// use to compare a photo with renders of it.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace propcam::inference {

inline constexpr double kLumaRed = 0.2126, kLumaGreen = 0.7152, kLumaBlue = 0.0722;

inline double luminance(const cv::Vec3f& rgb) { return kLumaRed * rgb[0] + kLumaGreen * rgb[1] + kLumaBlue * rgb[2]; }

inline double luminance(const Eigen::Vector3d& rgb) { return kLumaRed * rgb.x() + kLumaGreen * rgb.y() + kLumaBlue * rgb.z(); }

// Per pixel, in float: CV_32FC3 in, CV_32F out.
inline cv::Mat luminance_image(const cv::Mat& rgb) {
  cv::Mat out;
  cv::transform(rgb, out, cv::Matx13f(static_cast<float>(kLumaRed), static_cast<float>(kLumaGreen), static_cast<float>(kLumaBlue)));
  return out;
}

}  // namespace propcam::inference
