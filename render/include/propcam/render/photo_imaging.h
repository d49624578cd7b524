// What the camera that took a photo did to it beyond light, estimated from
// the photo alone, and the same done to what we render into it, so that an
// inserted prop is as soft and as grainy as the photo around it:
//   - blur: a Gaussian point spread on top of a pixel's own footprint (lens,
//     demosaicing, resampling, JPEG), measured at isolated step edges (their
//     lower quartile) by re-blurring (Zhuo & Sim 2011), with the discrete
//     operators' own response calibrated out; in a noisy photo the edges
//     are found on the smoothed luminance and read summed along each edge,
//     so that noise does not read as sharpness;
//   - noise: a noise level function per channel in display values (the
//     signal-dependent sensor noise after the tone curve), the lower
//     envelope of a Laplacian-like residual (Immerkaer 1996) over 8x8 blocks,
//     binned by intensity (Liu et al. 2006's idea, without their prior);
//   - defocus: where the inferred depth is given, the edges' blur read per
//     band of depth and fitted by a thin lens's circle of confusion, which
//     grows with |1/z - 1/z_focus|; kept only where the photo shows it.
// Our renderer's pixel is a box with no further blur, so the photo's blur is
// what the prop lacks; its noise lacks the photo's noise less its own.
#pragma once

#include <opencv2/core.hpp>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "propcam/render/vignetting.h"

namespace propcam::render {

// Intensity bins of the noise level function over display values [0, 1].
constexpr int kNoiseBins = 8;

struct NoiseLevelFunction {
  // Standard deviation in display values ([0, 1]) per bin and channel (RGB);
  // every bin filled (bins without blocks take the nearest measured bin).
  std::array<std::array<float, 3>, kNoiseBins> sigma{};
  // Linear interpolation between bin centres, clamped at the ends.
  float at(int channel, float display_value) const;
  // The median over bins and channels, in 8-bit levels.
  double median_8bit() const;
};

// The blur of the edges in one band of depth.
struct DepthBandBlur {
  double dioptres = 0.0;  // the band's median inverse depth, 1/m
  double sigma_px = 0.0;
  int edges = 0;
};

// Blur that grows away from a focus depth: sigma(z)^2 = base^2 +
// (per_dioptre * |1/z - focus_dioptres|)^2, a thin lens's circle of
// confusion (proportional to |1/z - 1/z_focus|) on top of the photo's own
// blur. Read between the nearest and farthest bands measured, never beyond.
struct Defocus {
  bool found = false;
  double base_sigma_px = 0.0;
  double focus_dioptres = 0.0;        // 1/m; 0 is focused at infinity
  double sigma_px_per_dioptre = 0.0;  // px * m
  double min_dioptres = 0.0, max_dioptres = 0.0;  // the bands' range
  std::vector<DepthBandBlur> bands;   // what it was fitted to (also when not found)
  double sigma_at(double depth_m) const;
};

struct PhotoImaging {
  bool blur_measured = false;   // enough isolated edges to tell
  double blur_sigma_px = 0.0;   // Gaussian sigma beyond a box pixel
  int blur_edges = 0;           // edge pixels the estimate is the lower quartile of
  bool blur_read_through_noise = false;  // a noisy photo's: edges found smoothed, read summed along each edge
  Defocus defocus;              // where the photo's blur grows with depth
  bool noise_measured = false;  // enough flat blocks to tell
  NoiseLevelFunction noise;
  int noise_blocks = 0;         // blocks the lower envelope was taken over
  double seconds = 0.0;
  // The blur at a depth (camera z, m): the defocus's where it was found and
  // the depth is known (> 0, finite), else the photo's one blur.
  double blur_sigma_at(double depth_m) const;
};

// Below this sigma an edge is as sharp as our render's (box pixels): no blur is matched.
constexpr double kMinMatchedBlurPx = 0.45;
// Below this (8-bit levels, the median of the noise level function) the
// photo is as clean as an 8-bit file of our render: no noise is matched.
constexpr double kMinMatchedNoise8bit = 0.8;

// `display` CV_32FC3 in [0, 1] (an 8-bit file's values / 255). `mask`
// (CV_8U, optional) limits the blocks to where it is non-zero.
NoiseLevelFunction estimate_noise_level(const cv::Mat& display, const cv::Mat& mask, int* blocks_used = nullptr);

// `linear` CV_32FC3 or CV_32F, linear light. `mask` (CV_8U, optional) limits
// the edges to where it is non-zero. Returns the blur sigma in pixels of the
// isolated step edges found, their lower quartile (a photo's edges are its
// point spread or wider); 0 when `edges_used` is 0.
// A photo's blur needs this many edge pixels to be told.
constexpr int kMinBlurEdges = 30;
double estimate_edge_blur(const cv::Mat& linear, const cv::Mat& mask = {}, int* edges_used = nullptr,
                          int min_edges = kMinBlurEdges);

// The noise of one region (CV_8U mask), per channel in display values: the
// median absolute Immerkaer response, for a region too small for the level
// function's blocks (a prop's inside). Zero below kMinRegionNoisePixels;
// `pixels` gets the region's size.
constexpr int kMinRegionNoisePixels = 64;
std::array<float, 3> region_noise_sigma(const cv::Mat& display, const cv::Mat& mask, int* pixels = nullptr);

// Defocus is told from the bands' blur only when the fit explains it and it
// spans enough: bands with enough edges, the fitted blur's range across
// them, bands whose blur is kMinDefocusRatio times the sharpest's (or
// kMinMatchedBlurPx's), and the fit's residual against a single blur's.
constexpr int kDefocusBands = 5;
constexpr int kMinDefocusBands = 3;
constexpr double kMinDefocusRangePx = 0.6;
constexpr double kMinDefocusRatio = 1.5;
constexpr int kMinWideDefocusBands = 2;
constexpr double kMaxDefocusResidualShare = 0.5;

// All three, on a photo decoded with the sRGB curve
// (capture::load_photo_linear). `depth` (CV_32F metres along camera z, any
// size: resized to the photo's; <= 0, non-finite or >= kSkyDepthM is no
// surface) is optional: without it no defocus is looked for.
PhotoImaging estimate_photo_imaging(const cv::Mat& photo_srgb_linear, const cv::Mat& depth = {});

// The camera match applied to a composite.
struct CameraMatchOptions {
  bool blur = true;
  bool noise = true;
  // The prop's depth (camera z of its base, m), for a photo whose blur grows
  // with depth; 0: unknown, the photo's one blur.
  double prop_depth_m = 0.0;
  // The lens's vignetting from the camera's calibration (a board's
  // board.json, `propcam composite --vignetting`), and where it came from;
  // unknown: none applied (a photo alone cannot tell it).
  Vignetting vignetting;
  std::string vignetting_source;
  uint64_t seed = 1;  // the matched noise is a pure function of (seed, pixel around the prop, channel)
};

struct CameraMatchStep {
  std::string effect;  // "blur" | "vignette" | "noise", in the order applied
  bool applied = false;
  std::string why;
};

struct CameraMatchReport {
  std::vector<CameraMatchStep> steps;
  double blur_sigma_px = 0.0;        // applied to the prop's change
  double vignette_gain = 1.0;        // the lens's gain at the prop's centre, applied to its pixels
  double noise_added_8bit = 0.0;     // median sigma added to the prop's pixels
  double prop_noise_8bit = 0.0;      // the render's own noise on them, measured
  double seconds = 0.0;
};

// The photo's blur given to what the prop adds: the prop's layer (its
// pixels weighted by `coverage`, CV_32F in [0, 1], plus the change it makes
// to the rest) blurred and laid over the photo through the blurred
// coverage, so that the photo's pixels hidden by the prop do not show
// through. Linear images in one space; pixels farther than the kernel's
// reach from the prop and its change stay bit-identical.
// `blurred_coverage` (optional) gets the coverage as blurred.
cv::Mat blur_change(const cv::Mat& photo_linear, const cv::Mat& composite_linear, const cv::Mat& coverage,
                    double sigma_px, cv::Mat* blurred_coverage = nullptr);

// Noise of the photo's level function, less what the prop's pixels already
// carry, added to them (weighted by `coverage`, CV_32F in [0, 1]); `display`
// CV_32FC3 in [0, 1]. The shadow a prop casts keeps the photo's own noise.
cv::Mat add_matched_noise(const cv::Mat& display, const cv::Mat& coverage, const NoiseLevelFunction& photo_noise,
                          uint64_t seed, CameraMatchReport* report = nullptr);

// Each step where the estimate (or the camera's calibration) says the photo
// has it, on a composite in the photo's response-linear space
// (capture::srgb_linear_to_response_linear with `response_gamma`): blur and
// the vignette there, then noise in display values (the sensor's, after the
// lens). Returns the
// matched composite in the same space.
cv::Mat match_camera(const cv::Mat& photo_linear, const cv::Mat& composite_linear, const cv::Mat& coverage,
                     const PhotoImaging& imaging, const CameraMatchOptions& options, double response_gamma,
                     CameraMatchReport* report = nullptr);

}  // namespace propcam::render
