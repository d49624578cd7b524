#include "propcam/inference/poisson.h"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace propcam::inference {

cv::Mat integrate_gradients(const cv::Mat& gx_in, const cv::Mat& gy_in) {
  if (gx_in.empty() || gx_in.size() != gy_in.size() || gx_in.channels() != 1 || gy_in.channels() != 1)
    throw std::invalid_argument("integrate_gradients: need two single-channel fields of one size");
  // OpenCV's DCT takes even sizes only: pad with a copy of the last row or
  // column (zero gradient into it), which keeps the Neumann solution.
  const int h0 = gx_in.rows, w0 = gx_in.cols;
  const int h = h0 + (h0 % 2), w = w0 + (w0 % 2);
  cv::Mat gx(h, w, CV_64F, cv::Scalar(0)), gy(h, w, CV_64F, cv::Scalar(0));
  gx_in.convertTo(gx(cv::Rect(0, 0, w0, h0)), CV_64F);
  gy_in.convertTo(gy(cv::Rect(0, 0, w0, h0)), CV_64F);
  // Toward the copy the step is 0; along the copy it repeats the last row/column.
  if (w > w0) {
    gx.col(w0 - 1).setTo(0);
    gy.col(w0 - 1).copyTo(gy.col(w0));
  }
  if (h > h0) {
    gy.row(h0 - 1).setTo(0);
    gx.row(h0 - 1).copyTo(gx.row(h0));
  }
  // Divergence of g with the boundary's missing neighbours contributing
  // nothing (Neumann): the right-hand side of the normal equations.
  cv::Mat div(h, w, CV_64F, cv::Scalar(0));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double d = 0;
      if (x + 1 < w) d += gx.at<double>(y, x);
      if (x > 0) d -= gx.at<double>(y, x - 1);
      if (y + 1 < h) d += gy.at<double>(y, x);
      if (y > 0) d -= gy.at<double>(y - 1, x);
      div.at<double>(y, x) = d;
    }
  cv::Mat spectrum;
  cv::dct(div, spectrum);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      // Eigenvalues of the Neumann Laplacian in the DCT-II basis.
      const double lambda = 2.0 * std::cos(std::numbers::pi * x / w) + 2.0 * std::cos(std::numbers::pi * y / h) - 4.0;
      spectrum.at<double>(y, x) = (x == 0 && y == 0) ? 0.0 : spectrum.at<double>(y, x) / lambda;
    }
  cv::Mat u;
  cv::idct(spectrum, u);
  u = u(cv::Rect(0, 0, w0, h0)).clone();
  return u - cv::mean(u)[0];
}

}  // namespace propcam::inference
