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

void check_fit_sizes(const IntensityFitProblem& p) {
  const size_t pixels = p.target.size();
  for (const auto& b : p.basis)
    if (b.size() != pixels) throw std::invalid_argument("fit_intensities: a basis render has the wrong pixel count");
  if ((!p.noise.empty() && p.noise.size() != p.basis.size()) || (!p.lower.empty() && p.lower.size() != p.basis.size()) ||
      (!p.upper.empty() && p.upper.size() != p.basis.size()))
    throw std::invalid_argument("fit_intensities: noise and bounds need one value per basis render");
}

// The problem in the fit's own units: targets clipped to what a camera can
// encode, and each basis scaled so that alone it matches the photo's mean.
struct NormalisedFit {
  int sources = 0;
  size_t pixels = 0;
  std::vector<double> target;         // encoded, in [0, 1]
  std::vector<double> target_linear;  // linearised with the prior response
  std::vector<double> scale;          // normalised basis = scale * basis; 0: lights nothing
  std::vector<double> rows;           // row-major (pixel, source), normalised
};

// Targets outside [0, 1] (or not finite) are clipped: the camera cannot encode them.
std::vector<double> clipped_targets(const IntensityFitProblem& p) {
  const size_t pixels = p.target.size();
  std::vector<double> target(pixels);
  for (size_t i = 0; i < pixels; ++i) target[i] = std::isfinite(p.target[i]) ? std::clamp<double>(p.target[i], 0.0, 1.0) : 0.0;
  return target;
}

// Scale each basis so that alone it matches the photo's mean (linear):
// weights O(1), priors independent of exposure.
std::vector<double> basis_scales(const IntensityFitProblem& p, const std::vector<double>& target_linear) {
  const int sources = static_cast<int>(p.basis.size());
  const size_t pixels = p.target.size();
  double target_linear_mean = 0.0;
  for (double t : target_linear) target_linear_mean += t;
  target_linear_mean = std::max(target_linear_mean / pixels, kMinRenderedValue);
  std::vector<double> scale(sources, 0.0);
  for (int k = 0; k < sources; ++k) {
    double mean = 0.0;
    for (float v : p.basis[k]) mean += std::isfinite(v) ? std::max(0.0f, v) : 0.0f;
    mean /= pixels;
    scale[k] = mean > kMinBasisMean ? target_linear_mean / mean : 0.0;
  }
  return scale;
}

NormalisedFit normalised_problem(const IntensityFitProblem& p, const IntensityFitOptions& o) {
  NormalisedFit f;
  f.sources = static_cast<int>(p.basis.size());
  f.pixels = p.target.size();
  f.target = clipped_targets(p);
  f.target_linear.resize(f.pixels);
  for (size_t i = 0; i < f.pixels; ++i) f.target_linear[i] = std::pow(f.target[i], 1.0 / o.gamma0);
  f.scale = basis_scales(p, f.target_linear);
  f.rows.resize(f.pixels * f.sources);
  for (size_t i = 0; i < f.pixels; ++i)
    for (int k = 0; k < f.sources; ++k) {
      const float v = p.basis[k][i];
      f.rows[i * f.sources + k] = f.scale[k] * (std::isfinite(v) ? std::max(0.0f, v) : 0.0f);
    }
  return f;
}

// Bounds and current weights in normalised units; held weights do not move.
struct WeightBounds {
  std::vector<double> w, lo, hi;
  std::vector<bool> held;
  int free_count = 0;
};

// Lights that light nothing or are bounded to 0 are held at 0, measured
// ones (upper <= lower) at their value; the rest start with equal shares.
WeightBounds bounds_and_equal_shares(const IntensityFitProblem& p, const std::vector<double>& scale) {
  const int sources = static_cast<int>(p.basis.size());
  WeightBounds b;
  b.w.assign(sources, 0.0);
  b.lo.assign(sources, 0.0);
  b.hi.assign(sources, std::numeric_limits<double>::infinity());
  b.held.assign(sources, false);
  for (int k = 0; k < sources; ++k) {
    const double lower = p.lower.empty() ? 0.0 : std::max(0.0, p.lower[k]);
    const double upper = p.upper.empty() ? std::numeric_limits<double>::infinity() : p.upper[k];
    if (scale[k] == 0.0 || !(upper > 0.0)) {
      b.held[k] = true;  // lights nothing, or bounded to 0
      b.w[k] = 0.0;
    } else if (upper <= lower) {
      b.held[k] = true;  // fixed (measured)
      b.w[k] = lower / scale[k];
    } else {
      b.lo[k] = lower / scale[k];
      b.hi[k] = upper / scale[k];
      ++b.free_count;
    }
  }
  for (int k = 0; k < sources; ++k)
    if (!b.held[k]) b.w[k] = std::clamp(1.0 / b.free_count, b.lo[k], b.hi[k]);
  return b;
}

// Start from the bounded least-squares weights in the linear domain (the
// photo linearised with gamma0), by coordinate descent from equal shares:
// cheap, and a better start for the soft-L1 solves than equal shares.
void least_squares_start(const NormalisedFit& f, WeightBounds& b) {
  const int sources = f.sources;
  const std::vector<double>& y = f.target_linear;
  std::vector<double>& w = b.w;
  Eigen::MatrixXd gram = Eigen::MatrixXd::Zero(sources, sources);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(sources);
  for (size_t i = 0; i < f.pixels; ++i) {
    const Eigen::Map<const Eigen::VectorXd> r(&f.rows[i * sources], sources);
    gram.noalias() += r * r.transpose();
    rhs.noalias() += r * y[i];
  }
  for (int sweep = 0; sweep < kInitialSweeps; ++sweep)
    for (int k = 0; k < sources; ++k) {
      if (b.held[k] || !(gram(k, k) > 0)) continue;
      const double rest = rhs[k] - gram.row(k).dot(Eigen::Map<const Eigen::VectorXd>(w.data(), sources)) + gram(k, k) * w[k];
      w[k] = std::clamp(rest / gram(k, k), b.lo[k], b.hi[k]);
    }
  for (double& v : w)
    if (!std::isfinite(v)) v = 0.0;
}

// The weights for a fixed response: bounded Levenberg-Marquardt.
class WeightSolver {
 public:
  WeightSolver(const NormalisedFit& f, const WeightBounds& b, const IntensityFitProblem& p, const IntensityFitOptions& o)
      : f_(f), b_(b), p_(p), o_(o), a_(std::sqrt(std::max(o.smooth_abs_epsilon, 1e-300))) {}

  // Solves the weights not in `hold` for response g, starting from (and
  // writing to) w. Returns the objective (data, priors and the response's
  // prior), or +inf when the solve is unusable (w is then left as it was).
  double solve(const std::vector<bool>& hold, double g, std::vector<double>& w, IntensityFitResult& out) const {
    std::vector<int> free_index;
    for (int k = 0; k < f_.sources; ++k)
      if (!hold[k]) free_index.push_back(k);
    const int free_n = static_cast<int>(free_index.size());
    const double gamma_cost = response_prior_cost(g);
    const std::vector<double> held_sum = held_sums(hold, w);
    if (free_n == 0) return objective_at_held_weights(held_sum, g, gamma_cost, out);
    std::vector<double> trial(free_n);
    for (int j = 0; j < free_n; ++j) trial[j] = w[free_index[j]];
    ceres::Problem::Options po;
    po.loss_function_ownership = ceres::TAKE_OWNERSHIP;
    ceres::Problem problem(po);
    add_residuals(problem, free_index, held_sum, g, trial);
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options(), &problem, &summary);
    out.iterations += static_cast<int>(summary.iterations.size());
    ++out.solves;
    out.converged = summary.termination_type == ceres::CONVERGENCE;
    out.termination = summary.message;
    const bool usable = summary.IsSolutionUsable() && std::isfinite(summary.final_cost) &&
                        std::all_of(trial.begin(), trial.end(), [](double v) { return std::isfinite(v); });
    if (!usable) return std::numeric_limits<double>::infinity();
    for (int j = 0; j < free_n; ++j) w[free_index[j]] = trial[j];
    return (summary.final_cost + gamma_cost) / a_;  // in the objective's units
  }

 private:
  // The response's prior, soft |gamma - gamma0| as Ceres would weigh it
  // (lambda a^2 (sqrt(1 + r^2/a^2) - 1)): constant within a solve, it
  // ranks the responses tried.
  double response_prior_cost(double g) const {
    const double gamma_weight = o_.lambda_gamma + o_.lambda_gamma_per_pixel * f_.pixels;
    return gamma_weight * a_ * (std::hypot(a_, g - o_.gamma0) - a_);
  }

  // What the held weights add to each pixel.
  std::vector<double> held_sums(const std::vector<bool>& hold, const std::vector<double>& w) const {
    std::vector<double> held_sum(f_.pixels, 0.0);
    for (size_t i = 0; i < f_.pixels; ++i)
      for (int k = 0; k < f_.sources; ++k)
        if (hold[k]) held_sum[i] += w[k] * f_.rows[i * f_.sources + k];
    return held_sum;
  }

  // Nothing to solve: the objective at the held weights.
  double objective_at_held_weights(const std::vector<double>& held_sum, double g, double gamma_cost,
                                   IntensityFitResult& out) const {
    double cost = gamma_cost;
    for (size_t i = 0; i < f_.pixels; ++i) {
      const double r = f_.target[i] - std::pow(std::max(held_sum[i], kMinRenderedValue), g);
      cost += a_ * (std::hypot(a_, r) - a_);
    }
    ++out.solves;
    out.converged = true;
    out.termination = "every weight is held";
    return std::isfinite(cost) ? cost / a_ : std::numeric_limits<double>::infinity();
  }

  void add_residuals(ceres::Problem& problem, const std::vector<int>& free_index, const std::vector<double>& held_sum,
                     double g, std::vector<double>& trial) const {
    const int free_n = static_cast<int>(free_index.size());
    // Q: per-pixel soft |.|, summed over pixels as in the paper.
    for (size_t i = 0; i < f_.pixels; ++i)
      problem.AddResidualBlock(
          new PixelResidual(&f_.rows[i * f_.sources], free_index.data(), free_n, held_sum[i], g, f_.target[i]),
          new ceres::SoftLOneLoss(a_), trial.data());
    // P: sparsity plus the basis-noise prior, |w_k| (1 + N_k) for w_k >= 0.
    for (int j = 0; j < free_n; ++j) {
      const int k = free_index[j];
      const double noise = p_.noise.empty() ? 0.0 : std::max(0.0, p_.noise[k]);
      problem.AddResidualBlock(new WeightResidual(j, free_n),
                               new ceres::ScaledLoss(new ceres::SoftLOneLoss(a_), o_.lambda_prior * (1.0 + noise),
                                                     ceres::TAKE_OWNERSHIP),
                               trial.data());
    }
    for (int j = 0; j < free_n; ++j) {
      const int k = free_index[j];
      problem.SetParameterLowerBound(trial.data(), j, b_.lo[k]);
      if (std::isfinite(b_.hi[k])) problem.SetParameterUpperBound(trial.data(), j, b_.hi[k]);
    }
  }

  ceres::Solver::Options solver_options() const {
    ceres::Solver::Options so;
    so.max_num_iterations = std::max(1, o_.max_iterations);
    so.max_solver_time_in_seconds = o_.max_seconds;
    so.linear_solver_type = ceres::DENSE_QR;
    so.num_threads = 1;  // deterministic
    so.function_tolerance = kFunctionTolerance;
    so.gradient_tolerance = kGradientTolerance;
    so.parameter_tolerance = kParameterTolerance;
    return so;
  }

  const NormalisedFit& f_;
  const WeightBounds& b_;
  const IntensityFitProblem& p_;
  const IntensityFitOptions& o_;
  const double a_;
};

struct BestFit {
  double gamma = 0.0, cost = 0.0;
  std::vector<double> w;
};

// Golden-section search for the lowest cost in [lo_g, hi_g]; `consider`
// solves at a response and returns its cost.
template <typename Consider>
void golden_section(double lo_g, double hi_g, const IntensityFitOptions& o, Consider&& consider) {
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

// The response: weights and response trade off along a shallow valley (a
// lower gamma brightens, so smaller weights do), where a joint solve
// stalled far from the optimum. So gamma is profiled: the weights are
// solved for each gamma of a log-spaced grid, then golden-section search
// between the best point's neighbours, warm-started from the best weights.
BestFit profile_gamma(const WeightSolver& solver, const std::vector<bool>& hold, std::vector<double>& w,
                      const IntensityFitOptions& o, IntensityFitResult& out) {
  BestFit best;
  best.gamma = o.gamma0;
  best.cost = solver.solve(hold, o.gamma0, w, out);
  best.w = w;
  const auto consider = [&](double g) {
    w = best.w;
    const double cost = solver.solve(hold, g, w, out);
    if (cost < best.cost) {
      best.cost = cost;
      best.gamma = g;
      best.w = w;
    }
    return cost;
  };
  if (!(o.fit_gamma && o.max_gamma > o.min_gamma && o.min_gamma > 0)) return best;
  const int n = std::max(3, o.gamma_grid);
  std::vector<double> grid(n);
  for (int i = 0; i < n; ++i)
    grid[i] = o.min_gamma * std::pow(o.max_gamma / o.min_gamma, static_cast<double>(i) / (n - 1));
  std::vector<double> costs(n);
  for (int i = 0; i < n; ++i) costs[i] = consider(grid[i]);
  const int b = static_cast<int>(std::min_element(costs.begin(), costs.end()) - costs.begin());
  // Bracket: the grid neighbours of the best grid point (and gamma0, if
  // it lies between them, is already a candidate).
  golden_section(grid[std::max(0, b - 1)], grid[std::min(n - 1, b + 1)], o, consider);
  return best;
}

// Zeroes and holds the free weights below prune_share of the total; true
// when one of them was not already zero.
bool prune_small_lights(const std::vector<bool>& held, double prune_share, std::vector<double>& w,
                        std::vector<bool>& hold, IntensityFitResult& out) {
  const int sources = static_cast<int>(w.size());
  double total = 0.0;
  for (int k = 0; k < sources; ++k) total += w[k];  // each normalised basis has the photo's mean
  bool pruned_any = false;
  for (int k = 0; k < sources; ++k)
    if (!held[k] && w[k] < prune_share * total) {
      pruned_any = pruned_any || w[k] > 0.0;
      w[k] = 0.0;
      hold[k] = true;
      ++out.pruned;
    }
  return pruned_any;
}

// Mean |I - (Rw)^gamma| over the pixels (encoded units).
double mean_data_error(const NormalisedFit& f, const std::vector<double>& w, double gamma) {
  double data_error = 0.0;
  for (size_t i = 0; i < f.pixels; ++i) {
    double sum = 0.0;
    for (int k = 0; k < f.sources; ++k) sum += w[k] * f.rows[i * f.sources + k];
    data_error += std::abs(f.target[i] - std::pow(std::max(sum, kMinRenderedValue), gamma));
  }
  return data_error / f.pixels;
}

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
  check_fit_sizes(p);
  const int sources = static_cast<int>(p.basis.size());
  const size_t pixels = p.target.size();
  IntensityFitResult out;
  out.weights = Eigen::VectorXd::Zero(sources);
  out.gamma = o.gamma0;
  if (sources == 0 || pixels == 0) {
    out.termination = sources == 0 ? "no light sources" : "no pixels to fit";
    return out;
  }
  const NormalisedFit fit = normalised_problem(p, o);
  WeightBounds bounds = bounds_and_equal_shares(p, fit.scale);
  least_squares_start(fit, bounds);
  const std::vector<double> w_start = bounds.w;
  const WeightSolver solver(fit, bounds, p, o);

  std::vector<bool> hold = bounds.held;
  const BestFit best = profile_gamma(solver, hold, bounds.w, o, out);
  std::vector<double> w = best.w;
  double gamma = best.gamma;
  if (!std::isfinite(best.cost)) {
    w = w_start;  // nothing usable: the least-squares start, prior response
    gamma = o.gamma0;
    out.converged = false;
  }
  // Prune lights that add (almost) nothing, then settle the rest without them.
  if (prune_small_lights(bounds.held, o.prune_share, w, hold, out) && std::count(hold.begin(), hold.end(), false) > 0)
    solver.solve(hold, gamma, w, out);

  out.data_error = mean_data_error(fit, w, gamma);
  for (int k = 0; k < sources; ++k) out.weights[k] = fit.scale[k] > 0 ? std::max(0.0, w[k]) * fit.scale[k] : 0.0;
  out.gamma = gamma;
  return out;
}

}  // namespace propcam::inference
