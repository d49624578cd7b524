#include "propcam/inference/depth_solve.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <opencv2/imgproc.hpp>
#include <opencv2/ximgproc/edge_filter.hpp>

#include "propcam/render/depth_mesh.h"

namespace propcam::inference {
namespace {

using Eigen::Vector3d;

// Depth the solve may reach: a hand's breadth to the far background. The
// bounds keep log-depth finite whatever the targets say.
constexpr double kMinDepthM = 0.05;
constexpr double kMaxDepthM = 500.0;
// Normals of near-degenerate triangles (three almost collinear points) are
// not trusted: the length of the cross product is floored by this.
constexpr double kNormalEpsilon = 1e-12;
// Manhattan / orientation residuals are products of unit components (at most
// 0.5): beyond this they are outliers (a real non-Manhattan object).
constexpr double kNormalLossScale = 0.15;
// A solve grid is never smaller than this per side (tiny photos still solve).
constexpr int kMinGridSide = 2;
// max_seconds guards against a hang only. Under ASan the bounded iterations
// take longer than 5 s on a busy 2-core machine, the guard fired part-way and
// two solves of the same input differed (GeometryHardCases determinism checks).
// gcc says ASan is on by __SANITIZE_ADDRESS__, clang (the asan and fuzz
// presets' compiler) only by __has_feature.
#if defined(__SANITIZE_ADDRESS__)
#define PROPCAM_ADDRESS_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define PROPCAM_ADDRESS_SANITIZED 1
#endif
#endif
#if defined(PROPCAM_ADDRESS_SANITIZED)
constexpr double kHangGuardScale = 20;
#else
constexpr double kHangGuardScale = 1;
#endif

struct Grid {
  int w = 0, h = 0;
  render::PinholeCamera camera;  // at the grid size
  cv::Mat log_target;             // CV_32F combined data target (for the initial guess)
  cv::Mat sky;                    // CV_8U
  cv::Mat labels;                 // CV_8U or empty
  std::vector<Vector3d> rays;     // world direction with camera z = 1 (depth scales it)
};

// Log-depth of a target resampled to the grid, ignoring pixels with no
// opinion: the area average of inverse depth (affine in the image over a
// plane, so a floor stays exact), then its log. `valid` (CV_32F) gets the
// fraction of the cell with an opinion times the target's confidence.
void resample_target(const DepthTarget& t, int w, int h, cv::Mat& log_depth, cv::Mat& valid) {
  if (t.depth.empty() || t.depth.type() != CV_32F) throw std::invalid_argument("solve_depth: targets must be CV_32F depth maps");
  if (!t.confidence.empty() && (t.confidence.type() != CV_32F || t.confidence.size() != t.depth.size()))
    throw std::invalid_argument("solve_depth: a target's confidence must be CV_32F at its depth's size");
  cv::Mat inv(t.depth.size(), CV_32F, 0.f), ok(t.depth.size(), CV_32F, 0.f);
  for (int y = 0; y < t.depth.rows; ++y)
    for (int x = 0; x < t.depth.cols; ++x) {
      const float d = t.depth.at<float>(y, x);
      if (!std::isfinite(d) || d <= 0) continue;
      float c = t.confidence.empty() ? 1.f : t.confidence.at<float>(y, x);
      if (!std::isfinite(c)) c = 0;
      c = std::clamp(c, 0.f, 1.f);
      const double clamped = std::clamp(static_cast<double>(d), kMinDepthM, kMaxDepthM);
      inv.at<float>(y, x) = static_cast<float>(1.0 / clamped) * c;
      ok.at<float>(y, x) = c;
    }
  cv::resize(inv, log_depth, cv::Size(w, h), 0, 0, cv::INTER_AREA);
  cv::resize(ok, valid, cv::Size(w, h), 0, 0, cv::INTER_AREA);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float v = valid.at<float>(y, x);
      const float mean_inv = v > 1e-4f ? log_depth.at<float>(y, x) / v : 0.f;
      log_depth.at<float>(y, x) = mean_inv > 0 ? -std::log(mean_inv) : 0.f;
    }
}

// World-frame normal of the triangle (P_i, P_right, P_down) from log-depths.
template <typename T>
Eigen::Matrix<T, 3, 1> triangle_normal(const T& zi, const T& zr, const T& zd, const Vector3d& ri, const Vector3d& rr,
                                       const Vector3d& rd) {
  const Eigen::Matrix<T, 3, 1> pi = ri.cast<T>() * exp(zi);
  const Eigen::Matrix<T, 3, 1> pr = rr.cast<T>() * exp(zr);
  const Eigen::Matrix<T, 3, 1> pd = rd.cast<T>() * exp(zd);
  const Eigen::Matrix<T, 3, 1> n = (pr - pi).cross(pd - pi);
  const T len = sqrt(n.squaredNorm() + T(kNormalEpsilon) * exp(T(2.0) * zi) * exp(T(2.0) * zi));
  return n / len;
}

struct DataResidual {
  double target, sqrt_weight;
  template <typename T>
  bool operator()(const T* z, T* r) const {
    r[0] = T(sqrt_weight) * (z[0] - T(target));
    return true;
  }
};

struct ManhattanResidual {
  Vector3d ri, rr, rd;
  double sqrt_weight;
  template <typename T>
  bool operator()(const T* zi, const T* zr, const T* zd, T* r) const {
    const auto n = triangle_normal(zi[0], zr[0], zd[0], ri, rr, rd);
    r[0] = T(sqrt_weight) * n.x() * n.y();
    r[1] = T(sqrt_weight) * n.y() * n.z();
    r[2] = T(sqrt_weight) * n.x() * n.z();
    return true;
  }
};

struct OrientationResidual {
  Vector3d ri, rr, rd;
  int axis;  // 0,1,2: the normal should be along this world axis
  double sqrt_weight;
  template <typename T>
  bool operator()(const T* zi, const T* zr, const T* zd, T* r) const {
    const auto n = triangle_normal(zi[0], zr[0], zd[0], ri, rr, rd);
    r[0] = T(sqrt_weight) * n((axis + 1) % 3);
    r[1] = T(sqrt_weight) * n((axis + 2) % 3);
    return true;
  }
};

// Second difference of three consecutive 3D points, relative to the middle
// depth: zero on any plane seen along a straight pixel row or column.
struct SmoothnessResidual {
  Vector3d ra, rb, rc;
  double sqrt_weight;
  template <typename T>
  bool operator()(const T* za, const T* zb, const T* zc, T* r) const {
    const T db = exp(zb[0]);
    const Eigen::Matrix<T, 3, 1> d2 = ra.cast<T>() * exp(za[0]) - T(2.0) * rb.cast<T>() * db + rc.cast<T>() * exp(zc[0]);
    for (int k = 0; k < 3; ++k) r[k] = T(sqrt_weight) * d2(k) / db;
    return true;
  }
};

Grid make_grid(const DepthProblem& p, const DepthSolveOptions& o, cv::Mat& target_sum, std::vector<cv::Mat>& logs,
               std::vector<cv::Mat>& valids) {
  Grid g;
  g.w = std::max(kMinGridSide, std::min(o.width, p.camera.width));
  g.h = std::max(kMinGridSide, static_cast<int>(std::lround(static_cast<double>(g.w) * p.camera.height / p.camera.width)));
  g.camera = p.camera.resized(g.w, g.h);
  g.rays.resize(static_cast<size_t>(g.w) * g.h);
  for (int y = 0; y < g.h; ++y)
    for (int x = 0; x < g.w; ++x)
      g.rays[static_cast<size_t>(y) * g.w + x] =
          g.camera.R_world_from_cam * Vector3d((x - g.camera.cx) / g.camera.fx, (y - g.camera.cy) / g.camera.fy, 1.0);
  g.sky = cv::Mat(g.h, g.w, CV_8U, cv::Scalar(0));
  if (!p.sky_mask.empty()) {
    cv::Mat skyf;
    p.sky_mask.convertTo(skyf, CV_32F, 1.0 / 255.0);
    cv::threshold(skyf, skyf, 0.0, 1.0, cv::THRESH_BINARY);
    cv::resize(skyf, skyf, cv::Size(g.w, g.h), 0, 0, cv::INTER_AREA);
    g.sky = skyf > 0.5f;
  }
  if (!p.orientation_labels.empty())
    cv::resize(p.orientation_labels, g.labels, cv::Size(g.w, g.h), 0, 0, cv::INTER_NEAREST);
  // The initial guess: the weighted mean of the targets' log-depths.
  cv::Mat num(g.h, g.w, CV_32F, 0.f);
  target_sum = cv::Mat(g.h, g.w, CV_32F, 0.f);
  for (const auto& t : p.targets) {
    cv::Mat l, v;
    resample_target(t, g.w, g.h, l, v);
    const float w = static_cast<float>(std::max(0.0, t.weight));
    num += l.mul(v) * w;
    target_sum += v * w;
    logs.push_back(l);
    valids.push_back(v);
  }
  g.log_target = cv::Mat(g.h, g.w, CV_32F);
  for (int y = 0; y < g.h; ++y)
    for (int x = 0; x < g.w; ++x) {
      const float s = target_sum.at<float>(y, x);
      g.log_target.at<float>(y, x) = s > 1e-6f ? num.at<float>(y, x) / s : std::nanf("");
    }
  return g;
}

// Pixels no target speaks for take the median of those that do.
double fill_initial_guess(cv::Mat& log_target, const cv::Mat& sky) {
  std::vector<float> known;
  for (int y = 0; y < log_target.rows; ++y)
    for (int x = 0; x < log_target.cols; ++x)
      if (!sky.at<uint8_t>(y, x) && std::isfinite(log_target.at<float>(y, x))) known.push_back(log_target.at<float>(y, x));
  if (known.empty()) return std::nan("");
  std::nth_element(known.begin(), known.begin() + known.size() / 2, known.end());
  const float med = known[known.size() / 2];
  for (int y = 0; y < log_target.rows; ++y)
    for (int x = 0; x < log_target.cols; ++x)
      if (!std::isfinite(log_target.at<float>(y, x))) log_target.at<float>(y, x) = med;
  return med;
}

// Cells where the solved surface bends or breaks: the second difference of
// inverse depth (zero on any plane) above kDepthEdgeRelative of the cell's
// own inverse depth, in either direction, grown by one cell.
constexpr float kDepthEdgeRelative = 0.02f;

cv::Mat depth_edge_cells(const cv::Mat& inv) {
  cv::Mat edge(inv.size(), CV_32F, cv::Scalar(0.f));
  for (int y = 0; y < inv.rows; ++y)
    for (int x = 0; x < inv.cols; ++x) {
      const float c = inv.at<float>(y, x);
      float bend = 0;
      if (x > 0 && x + 1 < inv.cols) bend = std::max(bend, std::abs(inv.at<float>(y, x - 1) - 2 * c + inv.at<float>(y, x + 1)));
      if (y > 0 && y + 1 < inv.rows) bend = std::max(bend, std::abs(inv.at<float>(y - 1, x) - 2 * c + inv.at<float>(y + 1, x)));
      if (bend > kDepthEdgeRelative * c) edge.at<float>(y, x) = 1.f;
    }
  cv::dilate(edge, edge, cv::Mat::ones(3, 3, CV_8U));
  return edge;
}

// Upsampling in inverse depth, which is affine in the image over any plane,
// so bilinear interpolation keeps floors and walls exactly planar. Only where
// the surface bends or breaks does a guided filter (guide: the photo's
// gamma-encoded luminance) snap depth to image edges; elsewhere it would
// print the photo's texture into the depth as ripples (and into the normals).
cv::Mat upsample_inverse_depth(const cv::Mat& inv_low, const cv::Size& size, const cv::Mat& guide_photo, double sigma_color) {
  cv::Mat up;
  cv::resize(inv_low, up, size, 0, 0, cv::INTER_LINEAR);
  if (guide_photo.empty() || inv_low.cols >= size.width) return up;
  cv::Mat edge;
  cv::resize(depth_edge_cells(inv_low), edge, size, 0, 0, cv::INTER_LINEAR);
  if (cv::countNonZero(edge) == 0) return up;
  cv::Mat gray;
  cv::cvtColor(guide_photo, gray, cv::COLOR_RGB2GRAY);
  cv::max(gray, 0.0, gray);
  cv::pow(gray, 1.0 / 2.2, gray);
  cv::min(gray, 1.0, gray);
  const int radius = std::max(1, static_cast<int>(std::lround(static_cast<double>(size.width) / inv_low.cols)));
  cv::Mat guided;
  cv::ximgproc::guidedFilter(gray, up, guided, radius, sigma_color * sigma_color);
  return up + edge.mul(guided - up);
}

void check_depth_inputs(const DepthProblem& p, const DepthSolveOptions& o) {
  if (p.camera.width <= 0 || p.camera.height <= 0) throw std::invalid_argument("solve_depth: empty camera");
  if (!p.sky_mask.empty() && (p.sky_mask.type() != CV_8U || p.sky_mask.size() != cv::Size(p.camera.width, p.camera.height)))
    throw std::invalid_argument("solve_depth: the sky mask must be CV_8U at the camera's size");
  if (!p.orientation_labels.empty() && p.orientation_labels.type() != CV_8U)
    throw std::invalid_argument("solve_depth: orientation labels must be CV_8U");
  if (!p.guide_photo.empty() && (p.guide_photo.type() != CV_32FC3 || p.guide_photo.size() != cv::Size(p.camera.width, p.camera.height)))
    throw std::invalid_argument("solve_depth: the guide photo must be CV_32FC3 at the camera's size");
  if (p.targets.empty()) throw std::invalid_argument("solve_depth: no depth target");
  if (o.width < 1 || o.max_iterations < 0 || !(o.max_seconds > 0)) throw std::invalid_argument("solve_depth: bad options");
}

// The unknowns: one log-depth per grid cell, row-major, starting at the targets' mean.
std::vector<double> initial_log_depths(const Grid& g) {
  const int n = g.w * g.h;
  std::vector<double> z(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) z[i] = g.log_target.at<float>(i / g.w, i % g.w);
  return z;
}

struct TermCounts {
  int data = 0, manhattan = 0, orientation = 0, smoothness = 0;
};

// Adds each solved cell's parameter and residuals to the problem. The order
// (cell by cell; within a cell data, Manhattan, orientation, smoothness) is
// the order Ceres lays out its Jacobian in, so it is kept as it is.
class DepthTermBuilder {
 public:
  DepthTermBuilder(ceres::Problem& problem, std::vector<double>& z, const Grid& g, const DepthProblem& p,
                   const std::vector<cv::Mat>& logs, const std::vector<cv::Mat>& valids, const DepthSolveOptions& o)
      : problem_(problem), z_(z), g_(g), p_(p), logs_(logs), valids_(valids), o_(o) {}

  void add_cell(int x, int y) {
    if (!solved(x, y)) return;
    double* zi = &z_[idx(x, y)];
    problem_.AddParameterBlock(zi, 1);
    problem_.SetParameterLowerBound(zi, 0, std::log(kMinDepthM));
    problem_.SetParameterUpperBound(zi, 0, std::log(kMaxDepthM));
    add_data_terms(x, y, zi);
    add_normal_terms(x, y, zi);
    add_smoothness_terms(x, y, zi);
  }

  const TermCounts& counts() const { return counts_; }

 private:
  bool solved(int x, int y) const { return x >= 0 && y >= 0 && x < g_.w && y < g_.h && !g_.sky.at<uint8_t>(y, x); }
  int idx(int x, int y) const { return y * g_.w + x; }

  // One term per target with an opinion on the cell.
  void add_data_terms(int x, int y, double* zi) {
    for (size_t t = 0; t < p_.targets.size(); ++t) {
      const double v = valids_[t].at<float>(y, x) * std::max(0.0, p_.targets[t].weight);
      if (v <= 1e-6) continue;
      problem_.AddResidualBlock(new ceres::AutoDiffCostFunction<DataResidual, 1, 1>(
                                    new DataResidual{logs_[t].at<float>(y, x), std::sqrt(v)}),
                                new ceres::SoftLOneLoss(o_.data_scale), zi);
      ++counts_.data;
    }
  }

  // Manhattan and orientation terms on the triangle to the right and below.
  void add_normal_terms(int x, int y, double* zi) {
    if (!(solved(x + 1, y) && solved(x, y + 1))) return;
    const Vector3d& ri = g_.rays[idx(x, y)];
    double* zr = &z_[idx(x + 1, y)];
    double* zd = &z_[idx(x, y + 1)];
    const Vector3d& rr = g_.rays[idx(x + 1, y)];
    const Vector3d& rd = g_.rays[idx(x, y + 1)];
    if (o_.use_manhattan && o_.weights.manhattan > 0) {
      problem_.AddResidualBlock(new ceres::AutoDiffCostFunction<ManhattanResidual, 3, 1, 1, 1>(
                                    new ManhattanResidual{ri, rr, rd, std::sqrt(o_.weights.manhattan)}),
                                new ceres::CauchyLoss(kNormalLossScale * std::sqrt(o_.weights.manhattan)), zi, zr, zd);
      ++counts_.manhattan;
    }
    const int label = g_.labels.empty() ? 0 : g_.labels.at<uint8_t>(y, x);
    if (o_.use_orientation && o_.weights.orientation > 0 && label >= 1 && label <= 3) {
      problem_.AddResidualBlock(new ceres::AutoDiffCostFunction<OrientationResidual, 2, 1, 1, 1>(
                                    new OrientationResidual{ri, rr, rd, label - 1, std::sqrt(o_.weights.orientation)}),
                                new ceres::CauchyLoss(kNormalLossScale * std::sqrt(o_.weights.orientation)), zi, zr, zd);
      ++counts_.orientation;
    }
  }

  // Second differences along the row, then the column, through the cell.
  void add_smoothness_terms(int x, int y, double* zi) {
    if (!(o_.use_smoothness && o_.weights.smoothness > 0)) return;
    const Vector3d& ri = g_.rays[idx(x, y)];
    const double sw = std::sqrt(o_.weights.smoothness);
    if (solved(x - 1, y) && solved(x + 1, y)) {
      problem_.AddResidualBlock(new ceres::AutoDiffCostFunction<SmoothnessResidual, 3, 1, 1, 1>(
                                    new SmoothnessResidual{g_.rays[idx(x - 1, y)], ri, g_.rays[idx(x + 1, y)], sw}),
                                new ceres::CauchyLoss(o_.smoothness_scale * sw), &z_[idx(x - 1, y)], zi, &z_[idx(x + 1, y)]);
      ++counts_.smoothness;
    }
    if (solved(x, y - 1) && solved(x, y + 1)) {
      problem_.AddResidualBlock(new ceres::AutoDiffCostFunction<SmoothnessResidual, 3, 1, 1, 1>(
                                    new SmoothnessResidual{g_.rays[idx(x, y - 1)], ri, g_.rays[idx(x, y + 1)], sw}),
                                new ceres::CauchyLoss(o_.smoothness_scale * sw), &z_[idx(x, y - 1)], zi, &z_[idx(x, y + 1)]);
      ++counts_.smoothness;
    }
  }

  ceres::Problem& problem_;
  std::vector<double>& z_;
  const Grid& g_;
  const DepthProblem& p_;
  const std::vector<cv::Mat>& logs_;
  const std::vector<cv::Mat>& valids_;
  const DepthSolveOptions& o_;
  TermCounts counts_;
};

TermCounts add_depth_terms(ceres::Problem& problem, std::vector<double>& z, const Grid& g, const DepthProblem& p,
                           const std::vector<cv::Mat>& logs, const std::vector<cv::Mat>& valids,
                           const DepthSolveOptions& o) {
  DepthTermBuilder builder(problem, z, g, p, logs, valids, o);
  for (int y = 0; y < g.h; ++y)
    for (int x = 0; x < g.w; ++x) builder.add_cell(x, y);
  return builder.counts();
}

ceres::Solver::Summary run_depth_solve(ceres::Problem& problem, const DepthSolveOptions& o) {
  ceres::Solver::Summary summary;
  if (problem.NumResidualBlocks() > 0 && o.max_iterations > 0) {
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::CGNR;
    so.max_linear_solver_iterations = 20;
    so.max_num_iterations = o.max_iterations;
    so.max_solver_time_in_seconds = o.max_seconds * kHangGuardScale;
    so.num_threads = std::max(1, o.num_threads);
    so.function_tolerance = 1e-6;
    so.logging_type = ceres::SILENT;
    ceres::Solve(so, &problem, &summary);
  }
  return summary;
}

// The solved grid as depth (sky cells at the sky's depth) into depth_low;
// returns it as inverse depth, which upsamples without bending planes.
cv::Mat solved_grid(const std::vector<double>& z, const Grid& g, double median_log, cv::Mat& depth_low) {
  depth_low = cv::Mat(g.h, g.w, CV_32F);
  cv::Mat inv_low(g.h, g.w, CV_32F);
  for (int y = 0; y < g.h; ++y)
    for (int x = 0; x < g.w; ++x) {
      double v = z[y * g.w + x];
      if (!std::isfinite(v)) v = std::isfinite(median_log) ? median_log : 0.0;
      v = std::clamp(v, std::log(kMinDepthM), std::log(kMaxDepthM));
      inv_low.at<float>(y, x) = static_cast<float>(std::exp(-v));
      depth_low.at<float>(y, x) = g.sky.at<uint8_t>(y, x) ? static_cast<float>(render::kSkyDepthM) : static_cast<float>(std::exp(v));
    }
  return inv_low;
}

// Full-size inverse depth back to depth, within the solve's bounds.
cv::Mat full_size_depth(const cv::Mat& inv_full, double median_log) {
  cv::Mat depth(inv_full.size(), CV_32F);
  for (int y = 0; y < inv_full.rows; ++y)
    for (int x = 0; x < inv_full.cols; ++x) {
      const float inv = inv_full.at<float>(y, x);
      const float d = std::isfinite(inv) && inv > 0 ? 1.f / inv : static_cast<float>(std::exp(std::isfinite(median_log) ? median_log : 0.0));
      depth.at<float>(y, x) = std::clamp(d, static_cast<float>(kMinDepthM), static_cast<float>(kMaxDepthM));
    }
  return depth;
}

// Sky pixels: at the sky's depth, their normals facing the camera.
void mark_sky(const DepthProblem& p, DepthSolution& s) {
  if (p.sky_mask.empty()) return;
  for (int y = 0; y < s.depth.rows; ++y)
    for (int x = 0; x < s.depth.cols; ++x)
      if (p.sky_mask.at<uint8_t>(y, x)) {
        s.depth.at<float>(y, x) = static_cast<float>(render::kSkyDepthM);
        const Vector3d d = -p.camera.ray_direction(x, y);
        s.normals.at<cv::Vec3f>(y, x) = cv::Vec3f(static_cast<float>(d.x()), static_cast<float>(d.y()), static_cast<float>(d.z()));
      }
}

StageReport depth_report(const Grid& g, const DepthSolveOptions& o, const ceres::Solver::Summary& summary,
                         int residual_blocks, const TermCounts& terms, std::chrono::steady_clock::time_point start) {
  StageReport r;
  r.stage = "depth";
  r.usable = true;
  const bool converged = summary.termination_type == ceres::CONVERGENCE;
  r.why = residual_blocks == 0           ? "nothing to solve (all sky)"
          : o.max_iterations == 0        ? "targets only (0 iterations)"
          : converged                    ? "converged"
                                         : std::string("stopped: ") + summary.message;
  r.iterations = static_cast<int>(summary.iterations.size());
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.error = summary.final_cost;
  r.details = {{"grid", {g.w, g.h}},
               {"initial_cost", summary.initial_cost},
               {"final_cost", summary.final_cost},
               {"converged", converged},
               {"solve_seconds", summary.total_time_in_seconds},
               {"linear_solver_seconds", summary.linear_solver_time_in_seconds},
               {"jacobian_seconds", summary.jacobian_evaluation_time_in_seconds},
               {"terms", {{"data", terms.data}, {"manhattan", terms.manhattan}, {"orientation", terms.orientation},
                          {"smoothness", terms.smoothness}}},
               {"weights", {o.use_manhattan ? o.weights.manhattan : 0.0, o.use_orientation ? o.weights.orientation : 0.0,
                            o.use_smoothness ? o.weights.smoothness : 0.0}}};
  return r;
}

}  // namespace

cv::Mat normals_from_depth(const cv::Mat& depth, const render::PinholeCamera& camera) {
  if (depth.type() != CV_32F || depth.cols != camera.width || depth.rows != camera.height)
    throw std::invalid_argument("normals_from_depth: depth must be CV_32F at the camera's size");
  cv::Mat normals(depth.size(), CV_32FC3);
  auto point = [&](int x, int y) {
    const double d = depth.at<float>(y, x);
    return Vector3d((x - camera.cx) / camera.fx * d, (y - camera.cy) / camera.fy * d, d);
  };
  for (int y = 0; y < depth.rows; ++y)
    for (int x = 0; x < depth.cols; ++x) {
      const int x0 = std::max(0, x - 1), x1 = std::min(depth.cols - 1, x + 1);
      const int y0 = std::max(0, y - 1), y1 = std::min(depth.rows - 1, y + 1);
      Vector3d n_cam = -point(x, y).normalized();
      if (x1 > x0 && y1 > y0) {
        Vector3d n = (point(x1, y) - point(x0, y)).cross(point(x, y1) - point(x, y0));
        if (n.norm() > kNormalEpsilon && n.allFinite()) {
          n.normalize();
          // Face the camera.
          if (n.dot(point(x, y)) > 0) n = -n;
          n_cam = n;
        }
      }
      if (!n_cam.allFinite()) n_cam = Vector3d(0, 0, -1);
      const Vector3d nw = camera.R_world_from_cam * n_cam;
      normals.at<cv::Vec3f>(y, x) = cv::Vec3f(static_cast<float>(nw.x()), static_cast<float>(nw.y()), static_cast<float>(nw.z()));
    }
  return normals;
}

DepthSolution solve_depth(const DepthProblem& p, const DepthSolveOptions& o) {
  const auto start = std::chrono::steady_clock::now();
  check_depth_inputs(p, o);
  cv::Mat target_sum;
  std::vector<cv::Mat> logs, valids;
  Grid g = make_grid(p, o, target_sum, logs, valids);
  const bool any_solved = cv::countNonZero(g.sky == 0) > 0;
  const double median_log = fill_initial_guess(g.log_target, g.sky);
  if (any_solved && !std::isfinite(median_log))
    throw std::invalid_argument("solve_depth: no target gives a depth for any non-sky pixel");

  std::vector<double> z = initial_log_depths(g);
  ceres::Problem problem;
  const TermCounts terms = add_depth_terms(problem, z, g, p, logs, valids, o);
  const ceres::Solver::Summary summary = run_depth_solve(problem, o);

  // Back to depth: the solved grid, then edge-aware to full size.
  DepthSolution s;
  const cv::Mat inv_low = solved_grid(z, g, median_log, s.depth_low);
  const cv::Size full(p.camera.width, p.camera.height);
  s.depth = full_size_depth(upsample_inverse_depth(inv_low, full, p.guide_photo, o.guide_sigma_color), median_log);
  s.normals = normals_from_depth(s.depth, p.camera);
  mark_sky(p, s);
  s.report = depth_report(g, o, summary, problem.NumResidualBlocks(), terms, start);
  return s;
}

}  // namespace propcam::inference
