// Poisson integration of a gradient field with Neumann boundaries by the
// discrete cosine transform: one forward and one inverse DCT, O(N log N) —
// a 1024x768 field in tens of milliseconds, where conjugate gradients take
// seconds.
#pragma once

#include <opencv2/core.hpp>

namespace propcam::inference {

// Finds u (CV_64F, the size of gx) minimising sum |grad u - g|^2, where gx(y,x)
// is the target for u(y,x+1) - u(y,x) and gy(y,x) for u(y+1,x) - u(y,x) (the
// last column of gx and last row of gy are ignored). u has zero mean.
cv::Mat integrate_gradients(const cv::Mat& gx, const cv::Mat& gy);

}  // namespace propcam::inference
