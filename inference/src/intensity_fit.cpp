#include "propcam/inference/intensity_fit.h"

#include <ceres/ceres.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "luminance.h"

namespace propcam::inference {
namespace {

// A basis render whose mean is below this lights nothing the fit can see:
// its weight stays 0.
constexpr double kMinBasisMean = 1e-12;
// The rendered sum is floored here before the response is applied: x^gamma
// has an infinite slope at 0 for gamma < 1.
constexpr double kMinRenderedValue = 1e-6;
// Ceres stops when the cost changes by less than this share per step, or the
// step or gradient is this small. Soft-L1 costs converge slowly under
// Levenberg-Marquardt; Ceres' defaults (1e-6) stopped 1% short on exact data.
constexpr double kFunctionTolerance = 1e-9;
constexpr double kGradientTolerance = 1e-12;
constexpr double kParameterTolerance = 1e-8;
// Coordinate-descent sweeps of the linear least-squares start.
constexpr int kInitialSweeps = 50;
// The response's search ends when its bracket is this narrow.
constexpr double kGammaTolerance = 1e-3;

// One pixel's residual I_i - (c_i + sum_j w_j b_ij)^gamma over the free
// weights w (one parameter block), analytic derivatives. The response gamma
// is fixed within a solve (it is profiled outside Ceres) and c_i is what the
// held weights add, so each pixel has one parameter block: Ceres' per-block
// overhead, not the arithmetic, was the fit's cost with one block per weight.
class PixelResidual : public ceres::CostFunction {
 public:
  PixelResidual(const double* basis_row, const int* free_index, int free_count, double held_sum, double gamma,
                double target)
      : basis_row_(basis_row), free_index_(free_index), free_count_(free_count), held_sum_(held_sum), gamma_(gamma),
        target_(target) {
    set_num_residuals(1);
    mutable_parameter_block_sizes()->push_back(free_count);
  }

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    const double* w = parameters[0];
    double sum = held_sum_;
    for (int j = 0; j < free_count_; ++j) sum += w[j] * basis_row_[free_index_[j]];
    const bool floored = !(sum > kMinRenderedValue);
    const double s = floored ? kMinRenderedValue : sum;
    const double encoded = std::pow(s, gamma_);
    residuals[0] = target_ - encoded;
    if (jacobians && jacobians[0]) {
      const double slope = floored ? 0.0 : gamma_ * encoded / s;  // d(s^gamma)/ds
      for (int j = 0; j < free_count_; ++j) jacobians[0][j] = -slope * basis_row_[free_index_[j]];
    }
    return std::isfinite(residuals[0]);
  }

 private:
  const double* basis_row_;
  const int* free_index_;
  int free_count_;
  double held_sum_, gamma_, target_;
};

// One free weight, w_j, for its prior |w_j|.
class WeightResidual : public ceres::CostFunction {
 public:
  WeightResidual(int index, int free_count) : index_(index) {
    set_num_residuals(1);
    mutable_parameter_block_sizes()->push_back(free_count);
  }

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    residuals[0] = parameters[0][index_];
    if (jacobians && jacobians[0]) {
      std::fill(jacobians[0], jacobians[0] + parameter_block_sizes()[0], 0.0);
      jacobians[0][index_] = 1.0;
    }
    return std::isfinite(residuals[0]);
  }

 private:
  int index_;
};

}  // namespace

double basis_noise(const cv::Mat& render, const cv::Mat& mask) {
  if (render.empty()) return 0.0;
  cv::Mat y;
  if (render.channels() == 3) y = luminance_image(render);
  else render.convertTo(y, CV_32F);
  double gradient = 0.0, value = 0.0;
  long count = 0;
  for (int r = 0; r + 1 < y.rows; ++r)
    for (int c = 0; c + 1 < y.cols; ++c) {
      if (!mask.empty() && !mask.at<uint8_t>(r, c)) continue;
      const double v = y.at<float>(r, c);
      gradient += std::hypot(y.at<float>(r, c + 1) - v, y.at<float>(r + 1, c) - v);
      value += v;
      ++count;
    }
  if (count == 0 || !(value > kMinBasisMean * count)) return 0.0;
  const double n = gradient / value;
  return std::isfinite(n) ? n : 0.0;
}

IntensityFitResult fit_intensities(const IntensityFitProblem& p, const IntensityFitOptions& o) {
  const int sources = static_cast<int>(p.basis.size());
  const size_t pixels = p.target.size();
  for (const auto& b : p.basis)
    if (b.size() != pixels) throw std::invalid_argument("fit_intensities: a basis render has the wrong pixel count");
  if ((!p.noise.empty() && p.noise.size() != p.basis.size()) || (!p.lower.empty() && p.lower.size() != p.basis.size()) ||
      (!p.upper.empty() && p.upper.size() != p.basis.size()))
    throw std::invalid_argument("fit_intensities: noise and bounds need one value per basis render");
  IntensityFitResult out;
  out.weights = Eigen::VectorXd::Zero(sources);
  out.gamma = o.gamma0;
  if (sources == 0 || pixels == 0) {
    out.termination = sources == 0 ? "no light sources" : "no pixels to fit";
    return out;
  }

  // Targets outside [0, 1] (or not finite) are clipped: the camera cannot encode them.
  std::vector<double> target(pixels);
  for (size_t i = 0; i < pixels; ++i) target[i] = std::isfinite(p.target[i]) ? std::clamp<double>(p.target[i], 0.0, 1.0) : 0.0;

  // The photo linearised with the prior response.
  std::vector<double> target_linear(pixels);
  for (size_t i = 0; i < pixels; ++i) target_linear[i] = std::pow(target[i], 1.0 / o.gamma0);
  // Scale each basis so that alone it matches the photo's mean (linear):
  // weights O(1), priors independent of exposure.
  double target_linear_mean = 0.0;
  for (double t : target_linear) target_linear_mean += t;
  target_linear_mean = std::max(target_linear_mean / pixels, kMinRenderedValue);
  std::vector<double> scale(sources, 0.0);  // normalised basis = scale * basis
  for (int k = 0; k < sources; ++k) {
    double mean = 0.0;
    for (float v : p.basis[k]) mean += std::isfinite(v) ? std::max(0.0f, v) : 0.0f;
    mean /= pixels;
    scale[k] = mean > kMinBasisMean ? target_linear_mean / mean : 0.0;
  }
  std::vector<double> rows(pixels * sources);  // row-major, normalised
  for (size_t i = 0; i < pixels; ++i)
    for (int k = 0; k < sources; ++k) {
      const float v = p.basis[k][i];
      rows[i * sources + k] = scale[k] * (std::isfinite(v) ? std::max(0.0f, v) : 0.0f);
    }

  // Bounds and start in normalised units.
  std::vector<double> w(sources), lo(sources, 0.0), hi(sources, std::numeric_limits<double>::infinity());
  std::vector<bool> held(sources, false);
  int free_count = 0;
  for (int k = 0; k < sources; ++k) {
    const double lower = p.lower.empty() ? 0.0 : std::max(0.0, p.lower[k]);
    const double upper = p.upper.empty() ? std::numeric_limits<double>::infinity() : p.upper[k];
    if (scale[k] == 0.0 || !(upper > 0.0)) {
      held[k] = true;  // lights nothing, or bounded to 0
      w[k] = 0.0;
    } else if (upper <= lower) {
      held[k] = true;  // fixed (measured)
      w[k] = lower / scale[k];
    } else {
      lo[k] = lower / scale[k];
      hi[k] = upper / scale[k];
      ++free_count;
    }
  }
  for (int k = 0; k < sources; ++k)
    if (!held[k]) w[k] = std::clamp(1.0 / free_count, lo[k], hi[k]);
  // Start from the bounded least-squares weights in the linear domain (the
  // photo linearised with gamma0), by coordinate descent from equal shares:
  // cheap, and a better start for the soft-L1 solves than equal shares.
  {
    const std::vector<double>& y = target_linear;
    Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(sources, sources);
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(sources);
    for (size_t i = 0; i < pixels; ++i) {
      const Eigen::Map<const Eigen::VectorXd> r(&rows[i * sources], sources);
      gram.noalias() += r * r.transpose();
      rhs.noalias() += r * y[i];
    }
    for (int sweep = 0; sweep < kInitialSweeps; ++sweep)
      for (int k = 0; k < sources; ++k) {
        if (held[k] || !(gram(k, k) > 0)) continue;
        const double rest = rhs[k] - gram.row(k).dot(Eigen::Map<const Eigen::VectorXd>(w.data(), sources)) + gram(k, k) * w[k];
        w[k] = std::clamp(rest / gram(k, k), lo[k], hi[k]);
      }
    for (double& v : w)
      if (!std::isfinite(v)) v = 0.0;
  }
  const std::vector<double> w_start = w;
  const double a = std::sqrt(std::max(o.smooth_abs_epsilon, 1e-300));

  // The weights for a fixed response: bounded Levenberg-Marquardt. Returns
  // the objective (data, priors and the response's prior), or +inf when the
  // solve is unusable (w is then left as it was).
  const auto solve_weights = [&](const std::vector<bool>& hold, double g) {
    std::vector<int> free_index;
    for (int k = 0; k < sources; ++k)
      if (!hold[k]) free_index.push_back(k);
    const int free_n = static_cast<int>(free_index.size());
    // The response's prior, soft |gamma - gamma0| as Ceres would weigh it
    // (lambda a^2 (sqrt(1 + r^2/a^2) - 1)): constant within the solve, it
    // ranks the responses tried.
    const double gamma_weight = o.lambda_gamma + o.lambda_gamma_per_pixel * pixels;
    const double gamma_cost = gamma_weight * a * (std::hypot(a, g - o.gamma0) - a);
    std::vector<double> held_sum(pixels, 0.0);
    for (size_t i = 0; i < pixels; ++i)
      for (int k = 0; k < sources; ++k)
        if (hold[k]) held_sum[i] += w[k] * rows[i * sources + k];
    if (free_n == 0) {
      // Nothing to solve: the objective at the held weights.
      double cost = gamma_cost;
      for (size_t i = 0; i < pixels; ++i) {
        const double r = target[i] - std::pow(std::max(held_sum[i], kMinRenderedValue), g);
        cost += a * (std::hypot(a, r) - a);
      }
      ++out.solves;
      out.converged = true;
      out.termination = "every weight is held";
      return std::isfinite(cost) ? cost / a : std::numeric_limits<double>::infinity();
    }
    std::vector<double> trial(free_n);
    for (int j = 0; j < free_n; ++j) trial[j] = w[free_index[j]];
    ceres::Problem::Options po;
    po.loss_function_ownership = ceres::TAKE_OWNERSHIP;
    ceres::Problem problem(po);
    // Q: per-pixel soft |.|, summed over pixels as in the paper.
    for (size_t i = 0; i < pixels; ++i)
      problem.AddResidualBlock(new PixelResidual(&rows[i * sources], free_index.data(), free_n, held_sum[i], g, target[i]),
                               new ceres::SoftLOneLoss(a), trial.data());
    // P: sparsity plus the basis-noise prior, |w_k| (1 + N_k) for w_k >= 0.
    for (int j = 0; j < free_n; ++j) {
      const int k = free_index[j];
      const double noise = p.noise.empty() ? 0.0 : std::max(0.0, p.noise[k]);
      problem.AddResidualBlock(new WeightResidual(j, free_n),
                               new ceres::ScaledLoss(new ceres::SoftLOneLoss(a), o.lambda_prior * (1.0 + noise),
                                                     ceres::TAKE_OWNERSHIP),
                               trial.data());
    }
    for (int j = 0; j < free_n; ++j) {
      const int k = free_index[j];
      problem.SetParameterLowerBound(trial.data(), j, lo[k]);
      if (std::isfinite(hi[k])) problem.SetParameterUpperBound(trial.data(), j, hi[k]);
    }
    ceres::Solver::Options so;
    so.max_num_iterations = std::max(1, o.max_iterations);
    so.max_solver_time_in_seconds = o.max_seconds;
    so.linear_solver_type = ceres::DENSE_QR;
    so.num_threads = 1;  // deterministic
    so.function_tolerance = kFunctionTolerance;
    so.gradient_tolerance = kGradientTolerance;
    so.parameter_tolerance = kParameterTolerance;
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem, &summary);
    out.iterations += static_cast<int>(summary.iterations.size());
    ++out.solves;
    out.converged = summary.termination_type == ceres::CONVERGENCE;
    out.termination = summary.message;
    const bool usable = summary.IsSolutionUsable() && std::isfinite(summary.final_cost) &&
                        std::all_of(trial.begin(), trial.end(), [](double v) { return std::isfinite(v); });
    if (!usable) return std::numeric_limits<double>::infinity();
    for (int j = 0; j < free_n; ++j) w[free_index[j]] = trial[j];
    return (summary.final_cost + gamma_cost) / a;  // in the objective's units
  };

  // The response: weights and response trade off along a shallow valley (a
  // lower gamma brightens, so smaller weights do), where a joint solve
  // stalled far from the optimum. So gamma is profiled: the weights are
  // solved for each gamma of a log-spaced grid, then golden-section search
  // between the best point's neighbours, warm-started from the best weights.
  std::vector<bool> hold = held;
  double best_gamma = o.gamma0;
  double best_cost = solve_weights(hold, o.gamma0);
  std::vector<double> best_w = w;
  const auto consider = [&](double g) {
    w = best_w;
    const double cost = solve_weights(hold, g);
    if (cost < best_cost) {
      best_cost = cost;
      best_gamma = g;
      best_w = w;
    }
    return cost;
  };
  if (o.fit_gamma && o.max_gamma > o.min_gamma && o.min_gamma > 0) {
    const int n = std::max(3, o.gamma_grid);
    std::vector<double> grid(n);
    for (int i = 0; i < n; ++i)
      grid[i] = o.min_gamma * std::pow(o.max_gamma / o.min_gamma, static_cast<double>(i) / (n - 1));
    std::vector<double> costs(n);
    for (int i = 0; i < n; ++i) costs[i] = consider(grid[i]);
    const int b = static_cast<int>(std::min_element(costs.begin(), costs.end()) - costs.begin());
    // Bracket: the grid neighbours of the best grid point (and gamma0, if
    // it lies between them, is already a candidate).
    double lo_g = grid[std::max(0, b - 1)], hi_g = grid[std::min(n - 1, b + 1)];
    constexpr double kGolden = 0.6180339887498949;
    double x1 = hi_g - kGolden * (hi_g - lo_g), x2 = lo_g + kGolden * (hi_g - lo_g);
    double f1 = consider(x1), f2 = consider(x2);
    for (int it = 0; it < o.gamma_refinements && hi_g - lo_g > kGammaTolerance; ++it) {
      if (f1 <= f2) {
        hi_g = x2, x2 = x1, f2 = f1;
        x1 = hi_g - kGolden * (hi_g - lo_g);
        f1 = consider(x1);
      } else {
        lo_g = x1, x1 = x2, f1 = f2;
        x2 = lo_g + kGolden * (hi_g - lo_g);
        f2 = consider(x2);
      }
    }
  }
  w = best_w;
  double gamma = best_gamma;
  if (!std::isfinite(best_cost)) {
    w = w_start;  // nothing usable: the least-squares start, prior response
    gamma = o.gamma0;
    out.converged = false;
  }
  // Prune lights that add (almost) nothing, then settle the rest without them.
  double total = 0.0;
  for (int k = 0; k < sources; ++k) total += w[k];  // each normalised basis has the photo's mean
  bool pruned_any = false;
  for (int k = 0; k < sources; ++k)
    if (!held[k] && w[k] < o.prune_share * total) {
      pruned_any = pruned_any || w[k] > 0.0;
      w[k] = 0.0;
      hold[k] = true;
      ++out.pruned;
    }
  if (pruned_any && std::count(hold.begin(), hold.end(), false) > 0) solve_weights(hold, gamma);

  double data_error = 0.0;
  for (size_t i = 0; i < pixels; ++i) {
    double sum = 0.0;
    for (int k = 0; k < sources; ++k) sum += w[k] * rows[i * sources + k];
    data_error += std::abs(target[i] - std::pow(std::max(sum, kMinRenderedValue), gamma));
  }
  out.data_error = data_error / pixels;
  for (int k = 0; k < sources; ++k) out.weights[k] = scale[k] > 0 ? std::max(0.0, w[k]) * scale[k] : 0.0;
  out.gamma = gamma;
  return out;
}

}  // namespace propcam::inference
