// A lens's vignetting: the fall-off of the light a lens passes toward the
// frame's corners, known from the camera's calibration (flat-field frames),
// not from the photo itself: one photo cannot tell a vignette from the
// scene's own fall-off (docs/camera_match.md, "Vignetting from one photo").
// The scene is inferred from the photo with it divided out, and the camera
// match darkens what the prop adds by it, as the lens darkened the photo.
//
// Model: V(r) = exp(r2 r^2 + r4 r^4), r the distance from the frame's centre
// over its half-diagonal (0 at the centre, 1 in the corners). A log-polynomial
// is always positive, and its fit to a flat field is linear.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace propcam::render {

// Coefficients beyond this are no lens's, and the gain at any r must stay in
// [kMinVignetteGain, kMaxVignetteGain].
constexpr double kMaxVignettingCoefficient = 5.0;
constexpr double kMinVignetteGain = 0.05;
constexpr double kMaxVignetteGain = 1.5;

struct Vignetting {
  double r2 = 0.0, r4 = 0.0;
  // A lens without vignetting is the same as none known.
  bool known() const { return r2 != 0.0 || r4 != 0.0; }
  // The gain at a normalised radius r in [0, 1] (clamped).
  double at_radius(double r) const;
  // The gain at pixel (x, y) of a frame of `size`, pixel centres at +0.5.
  double at_pixel(double x, double y, cv::Size size) const;
};

// Why a vignetting cannot be used ("" when it can): non-finite or too large
// coefficients, or a gain outside [kMinVignetteGain, kMaxVignetteGain].
std::string vignetting_problem(const Vignetting& v);

struct VignettingFit {
  Vignetting vignetting;
  double residual_rms = 0.0;  // of log luminance after the fit (a fraction: 0.01 is 1%)
  double gradient = 0.0;      // the light's own linear gradient across the frame taken out (log units per half-diagonal)
  int pixels = 0;             // the reduced frame's pixels the fit used
};

// A flat field's residual above this is not a flat field (a scene, a
// shadow, a lamp's spot): the fit refuses it.
constexpr double kMaxFlatFieldResidual = 0.03;
// A usable pixel is neither black nor clipped; at least this share must be.
constexpr double kMinFlatFieldUsableShare = 0.8;

// Fits the vignetting to flat-field frames: photos of an evenly lit, even
// surface (a white card filling the frame, a diffuser over the lens) in
// linear light (CV_32FC3, all the same size, the camera's still framing).
// They are averaged; log luminance is fitted by c + gx x + gy y + r2 r^2 +
// r4 r^4, the linear terms taking the light's own gradient. Throws
// std::invalid_argument naming the problem: no frames, different sizes,
// tiny, non-finite, too dark or clipped, or not flat (residual above
// kMaxFlatFieldResidual).
VignettingFit fit_vignetting(const std::vector<cv::Mat>& flat_fields_linear);

// A lens-free image as the lens would have taken it: each pixel times V
// (CV_32FC3 linear; a known fall-off put on test and bench photos).
cv::Mat vignette_image(const cv::Mat& linear, const Vignetting& vignetting);

// The photo as a lens without fall-off would have taken it: each pixel
// divided by V (CV_32FC3 linear). The scene is inferred from this, so that
// its lights and albedo are the scene's and not the lens's. Unknown
// vignetting returns the photo itself.
cv::Mat devignette(const cv::Mat& photo_linear, const Vignetting& vignetting);

// The lens's fall-off on what the prop adds, in place: the prop's layer —
// each changed pixel's value less the photo's uncovered share,
// (1 - coverage) * photo: the prop's own radiance and the light its shadow
// takes or its bounce adds, rendered from the lens-free scene — is scaled by
// V at the pixel. Linear images (CV_32FC3) in one space, `coverage` CV_32F in
// [0, 1]; pixels the prop neither covers nor changes keep their exact value.
void vignette_prop(const cv::Mat& photo_linear, cv::Mat& composite_linear, const cv::Mat& coverage,
                   const Vignetting& vignetting);

}  // namespace propcam::render
