// Edge-aware denoising of what the prop changes in the photo: the change
// layer (shadows, bounce light) and the prop's own pixels, filtered by an
// à-trous wavelet (Dammertz et al. 2010) whose edge-stopping functions follow
// SVGF (Schied et al. 2017): normals, depth, prop/background, and luminance
// relative to the estimated noise, so a converged pixel keeps its value.
//
// The filter works on illumination (change / albedo) and multiplies the
// albedo back, so texture is not blurred. Only pixels whose samples the prop
// changed are written; every other pixel of the photo stays bit-identical.
//
// Whether the filtered result is better is decided per tile without a
// reference, from two half buffers (even and odd samples): the filter of
// half A is compared with the independent half B. E|F(A) - B|^2 and
// E|A - B|^2 share B's variance, so F lowers the error where
// |F(A) - B|^2 < |A - B|^2 (the dual-buffer test of Rousselle et al. 2012).
#pragma once

#include <opencv2/core.hpp>
#include <vector>

namespace propcam::render {

struct DenoiseGuides {
  cv::Mat albedo;  // CV_32FC3 linear, what the camera ray hit first (prop or background)
  cv::Mat normal;  // CV_32FC3 unit world normals (0 where nothing was hit)
  cv::Mat depth;   // CV_32F metres along the camera axis (0 where nothing was hit)
  cv::Mat prop;    // CV_8U, 255 where the camera ray hit a prop
};

struct DenoiseOptions {
  int levels = 5;                 // à-trous passes, steps 1, 2, 4, ... pixels
  double luminance_sigma = 4.0;   // luminance difference, in noise standard deviations, at weight e^-1
  double normal_power = 64.0;     // weight (n_p . n_q)^power
  double depth_sigma = 0.02;      // relative depth difference per pixel of step at weight e^-1
  // A render session filters tiles with at most this many samples per pixel:
  // beyond it, against a converged reference, the filter stopped lowering the
  // composite's error (render/README.md, `propcam bench render`).
  int max_samples = 16;
};

// One buffer of a differential render, as the filter needs it.
struct ChangeBuffer {
  cv::Mat change;    // CV_32FC3: mean per-sample change (prop pixels: their radiance)
  cv::Mat variance;  // CV_32F: variance of that mean's luminance (0 where converged or untouched)
};

// The filtered change, written where `touched` (CV_8U) is non-zero and equal
// to `input.change` elsewhere. Pixels with partial prop coverage (silhouettes,
// `coverage` CV_32F strictly between 0 and 1) are kept as they are.
cv::Mat denoise_change(const ChangeBuffer& input, const cv::Mat& touched, const cv::Mat& coverage,
                       const DenoiseGuides& guides, const DenoiseOptions& options = {});

// Per tile: true where the filter lowers the error by the dual-buffer test on
// the halves `a` and `b` (filtered `a_filtered`), judged over touched pixels.
std::vector<bool> filter_helps_per_tile(const cv::Mat& a, const cv::Mat& a_filtered, const cv::Mat& b,
                                        const cv::Mat& touched, const std::vector<cv::Rect>& tiles);

}  // namespace propcam::render
