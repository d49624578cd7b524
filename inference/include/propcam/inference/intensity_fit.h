// Light intensities and the camera response from basis renders (Karsch et
// al. 2014, "Intensity estimation through rendering"): with R_k the scene
// rendered with source k alone at unit intensity and I the photo as the
// camera encoded it,
//
//   min_{w >= 0, gamma > 0}  Q(w, gamma) + lambda_P P(w) + lambda_gamma |gamma - gamma_0|
//   Q = sum_i | I_i - (sum_k w_k R_ik)^gamma |
//   P = sum_k (|w_k| + w_k N_k),  N_k = the basis render's noise (its mean
//       gradient magnitude over its mean value: noisy sources render slowly)
//
// with |x| ~ sqrt(x^2 + eps): the weights by Ceres (bounded Levenberg-
// Marquardt; each |.| a soft-L1 loss on its residual) for each response of a
// bounded 1D search over gamma. Each basis is first scaled so
// that it alone matches the photo's mean, so weights are O(1) and the priors
// mean the same at any exposure; the returned weights are in the basis
// renders' own units (physical radiance scales of the renderer's lights).
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace propcam::inference {

struct IntensityFitOptions {
  // As the paper: Q sums over the fit's pixels, so the priors weigh less the
  // more pixels there are (at 160x120, 0.1 is 5e-6 of a pixel-mean error).
  double lambda_prior = 0.1;   // lambda_P
  double lambda_gamma = 0.1;   // lambda_gamma, as the paper
  // Plus this much per fit pixel: a prior on the response that holds at any
  // fit resolution. On the pipeline's own estimates (rendered rooms encoded
  // with exponents 1.8, 2.2 and 2.6) the paper's weight let gamma absorb the
  // mismatch of estimated albedo and geometry (exponents 3.5-4.1 for all
  // three), so the default keeps the response near gamma0 unless the photo
  // strongly disagrees (docs/intensities.md, "Camera response").
  double lambda_gamma_per_pixel = 0.1;
  double gamma0 = 1.0 / 2.2;   // prior camera response exponent (encoded = linear^gamma)
  bool fit_gamma = true;       // false: gamma stays gamma0
  double min_gamma = 0.2, max_gamma = 1.5;
  double smooth_abs_epsilon = 1e-6;  // |x| ~ sqrt(x^2 + eps)
  int gamma_grid = 4;          // log-spaced responses tried in [min_gamma, max_gamma]
  int gamma_refinements = 5;   // golden-section steps around the best of them
  int max_iterations = 100;    // per weight solve
  double max_seconds = 2.0;    // per weight solve
  // A weight whose light contributes less than this share of the fitted
  // image's mean is pruned to zero (it costs render time, adds nothing).
  double prune_share = 1e-3;
};

struct IntensityFitProblem {
  // basis[k][i]: linear value of basis render k at fit pixel i (unit intensity).
  std::vector<std::vector<float>> basis;
  // target[i]: the photo's encoded value at fit pixel i (0..1, as the camera wrote it).
  std::vector<float> target;
  // noise[k]: N_k (empty: no noise prior).
  std::vector<double> noise;
  // Bounds on each weight (in the basis renders' units); lower == upper fixes
  // it (a measured source, e.g. a visible sky). Empty: [0, inf).
  std::vector<double> lower, upper;
};

struct IntensityFitResult {
  Eigen::VectorXd weights;  // >= 0, pruned ones exactly 0
  double gamma = 1.0 / 2.2;
  int iterations = 0;       // Levenberg-Marquardt iterations, all solves
  int solves = 0;           // weight solves (one per response tried)
  bool converged = false;   // the last solve's
  std::string termination;  // Ceres' message, or why the fit did not run
  double final_cost = 0.0;
  double data_error = 0.0;  // mean |I - (Rw)^gamma| at the solution (encoded units)
  int pruned = 0;
};

// Deterministic, bounded in iterations and time, always finite. Throws
// std::invalid_argument on inconsistent sizes.
IntensityFitResult fit_intensities(const IntensityFitProblem& problem, const IntensityFitOptions& options = {});

// N_k of a basis render (CV_32FC3 or CV_32FC1): mean gradient magnitude of
// its luminance over its mean luminance, over the pixels where mask != 0
// (empty mask: all). 0 for a black render.
double basis_noise(const cv::Mat& render, const cv::Mat& mask);

}  // namespace propcam::inference
