// Which sun candidate a street photo calls for, from the candidates' basis
// renders and the seen sky's (docs/streets_sun.md, "The choice of
// sun by what the sky cannot light").
#pragma once

#include <opencv2/core.hpp>
#include <vector>

namespace propcam::inference {

struct SunChoiceOptions {
  // The brightest diffuse reflectance (the albedo stage clamps to it): the
  // sky alone makes a surface at most this times its irradiance over pi.
  double max_albedo = 0.95;
  // A candidate lights a pixel when its shading relative to the sky's is
  // above this share of its own 95th percentile over the pixels it lights.
  double lit_share_of_peak = 0.25;
  // Candidates that light at least this share of the best candidate's count
  // of the must-be-sunlit pixels stay in the choice.
  double keep_share_of_best = 0.9;
  // Both the sky render and the albedo are blurred this much (pixels) before
  // their ratio, the sky's irradiance: the renders filter the albedo texture.
  double sky_irradiance_blur_px = 1.0;
};

struct SunChoice {
  int chosen = -1;                  // index into the candidates; -1: none given
  int must_be_sunlit = 0;           // pixels brighter than the sky alone can make them
  std::vector<double> sunlit_share; // per candidate: share of those it lights
  std::vector<double> agreement;    // per candidate: correlation of its relative shading with log luminance
};

// `candidates`: one basis render per sun (CV_32FC3, the photo's fit size);
// `sky`: the seen sky's basis render at its measured radiance (weight 1),
// over the same geometry and `albedo`; `photo` linear; `pixels` the fit's.
// A pixel brighter than max_albedo times the sky's irradiance must see the
// sun. The candidates that light most of those stay; of them, the one whose
// shading relative to the sky's (candidate over sky render: both carry the
// same albedo texture, which cancels) correlates best with the photo's log
// luminance is chosen. With no such pixel (an overcast or all-shaded street)
// the correlation alone chooses. Deterministic; finite for any input.
SunChoice choose_sun(const std::vector<cv::Mat>& candidates, const cv::Mat& sky, const cv::Mat& albedo,
                     const cv::Mat& photo, const std::vector<cv::Point>& pixels, const SunChoiceOptions& options = {});

}  // namespace propcam::inference
