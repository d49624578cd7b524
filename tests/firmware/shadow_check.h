// Shared check for composite tests: how much the floor beside a composited
// prop darkened (its shadow), as the ratio of mean luminance after / before.
#pragma once

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace propcam::firmware::testing {

inline double mean_luminance(const cv::Mat& rgb, const cv::Mat& mask) {
  cv::Mat grey;
  cv::transform(rgb, grey, cv::Matx13f(0.2126f, 0.7152f, 0.0722f));
  return cv::mean(grey, mask)[0];
}

// The floor around the prop's base: its bounding box widened by half its
// width on each side, around the bottom third, minus the prop itself.
inline cv::Mat floor_beside_prop(const cv::Mat& coverage) {
  const cv::Mat prop_mask = coverage > 0;
  const cv::Rect box = cv::boundingRect(prop_mask);
  cv::Rect ring(box.x - box.width / 2, box.y + box.height * 2 / 3, box.width * 2, box.height * 2 / 3);
  ring &= cv::Rect(0, 0, prop_mask.cols, prop_mask.rows);
  cv::Mat floor_mask = cv::Mat::zeros(prop_mask.size(), CV_8U);
  if (box.area() > 0) floor_mask(ring).setTo(255);
  floor_mask.setTo(0, prop_mask);
  return floor_mask;
}

// < 1 when the prop's shadow darkens the floor beside it.
inline double shadow_ratio(const cv::Mat& photo, const cv::Mat& composite, const cv::Mat& coverage) {
  const cv::Mat floor = floor_beside_prop(coverage);
  const double before = mean_luminance(photo, floor);
  return before > 0 ? mean_luminance(composite, floor) / before : 1.0;
}

struct ShadowPixels {
  int darker = 0;    // outside the prop, darker by more than the threshold
  int brighter = 0;  // outside the prop, brighter by more than the threshold (noise, bounce light)
  int prop = 0;      // pixels the prop covers
};

// Counts pixels beside the prop (within `reach` prop-box sizes) that the
// composite made visibly darker or brighter: a visible shadow is many more
// darker pixels than brighter ones, whatever its direction.
inline ShadowPixels shadow_pixels(const cv::Mat& photo, const cv::Mat& composite, const cv::Mat& coverage,
                                  double threshold = 0.1, double reach = 1.0) {
  ShadowPixels out;
  const cv::Mat prop_mask = coverage > 0;
  out.prop = cv::countNonZero(prop_mask);
  const cv::Rect box = cv::boundingRect(prop_mask);
  const int grow = static_cast<int>(reach * std::max(box.width, box.height));
  cv::Rect near(box.x - grow, box.y - grow, box.width + 2 * grow, box.height + 2 * grow);
  near &= cv::Rect(0, 0, photo.cols, photo.rows);
  cv::Mat before, after;
  cv::transform(photo, before, cv::Matx13f(0.2126f, 0.7152f, 0.0722f));
  cv::transform(composite, after, cv::Matx13f(0.2126f, 0.7152f, 0.0722f));
  for (int y = near.y; y < near.br().y; ++y)
    for (int x = near.x; x < near.br().x; ++x) {
      if (prop_mask.at<uint8_t>(y, x)) continue;
      const float b = before.at<float>(y, x), a = after.at<float>(y, x);
      if (a < b * (1 - threshold)) ++out.darker;
      else if (a > b * (1 + threshold)) ++out.brighter;
    }
  return out;
}

}  // namespace propcam::firmware::testing
