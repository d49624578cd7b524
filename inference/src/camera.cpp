#include "propcam/inference/camera.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <random>
#include <sstream>

namespace propcam::inference {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

constexpr double kDegToRad = std::numbers::pi / 180.0;
// Cross products shorter than this are treated as parallel (degenerate sample).
constexpr double kDegenerateCross = 1e-6;
// A direction with |z| below this is a vanishing point at infinity (it
// carries no information about the focal length).
constexpr double kFiniteVanishingZ = 0.15;
// Penalty per unit |log(f / prior)| that breaks ties toward the focal prior.
constexpr double kFocalPriorWeight = 0.03;
// The up direction must lie within this angle of the image's vertical axis.
constexpr double kMaxUpTiltDeg = 50.0;

struct LineNormal {
  Vector3d n;     // unit normal of the plane through the camera centre and the line
  double weight;  // line length in pixels
};

std::vector<LineNormal> interpretation_normals(const std::vector<LineSegment>& lines, double f, double cx, double cy) {
  std::vector<LineNormal> out;
  out.reserve(lines.size());
  for (const auto& l : lines) {
    const Vector3d a((l.a.x() - cx) / f, (l.a.y() - cy) / f, 1.0);
    const Vector3d b((l.b.x() - cx) / f, (l.b.y() - cy) / f, 1.0);
    Vector3d n = a.cross(b);
    const double len = n.norm();
    out.push_back({len > 0 ? Vector3d(n / len) : Vector3d::Zero(), len > 0 ? l.length() : 0.0});
  }
  return out;
}

// Soft support of three orthogonal directions: each line votes for the
// direction its interpretation plane contains best.
double score_frame(const std::vector<LineNormal>& normals, const std::array<Vector3d, 3>& dirs, double tolerance,
                   std::array<double, 3>* per_direction = nullptr, std::vector<int>* labels = nullptr) {
  double total = 0.0;
  if (per_direction) per_direction->fill(0.0);
  if (labels) labels->assign(normals.size(), -1);
  const double tol2 = tolerance * tolerance;
  for (size_t i = 0; i < normals.size(); ++i) {
    double best = 0.0;
    int best_k = -1;
    for (int k = 0; k < 3; ++k) {
      const double c = normals[i].n.dot(dirs[k]);
      const double vote = 1.0 - c * c / tol2;
      if (vote > best) {
        best = vote;
        best_k = k;
      }
    }
    if (best_k < 0) continue;
    total += best * normals[i].weight;
    if (per_direction) (*per_direction)[best_k] += normals[i].weight;
    if (labels) (*labels)[i] = best_k;
  }
  return total;
}

// Residual for one inlier line: the cosine between its interpretation-plane
// normal and its assigned direction. Parameters: rotation (angle-axis, 3) of
// the Manhattan frame in camera coordinates, and log focal length (1).
struct LineDirectionResidual {
  LineDirectionResidual(const LineSegment& l, double cx, double cy, int axis, double weight)
      : ax(l.a.x() - cx), ay(l.a.y() - cy), bx(l.b.x() - cx), by(l.b.y() - cy), axis(axis), weight(weight) {}

  template <typename T>
  bool operator()(const T* const angle_axis, const T* const log_focal, T* residual) const {
    const T f = exp(log_focal[0]);
    const T a[3] = {T(ax) / f, T(ay) / f, T(1)};
    const T b[3] = {T(bx) / f, T(by) / f, T(1)};
    T n[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    const T norm = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    T unit_axis[3] = {T(0), T(0), T(0)};
    unit_axis[axis] = T(1);
    T d[3];
    ceres::AngleAxisRotatePoint(angle_axis, unit_axis, d);
    residual[0] = T(weight) * (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) / norm;
    return true;
  }
  double ax, ay, bx, by;
  int axis;
  double weight;
};

Matrix3d frame_matrix(const std::array<Vector3d, 3>& dirs) {
  Matrix3d m;
  for (int k = 0; k < 3; ++k) m.col(k) = dirs[k];
  return m;
}

}  // namespace

const char* to_string(CameraCase c) {
  switch (c) {
    case CameraCase::ThreeVanishingPoints: return "three_vanishing_points";
    case CameraCase::TwoVanishingPoints: return "two_vanishing_points";
    case CameraCase::VerticalOnly: return "vertical_only";
    case CameraCase::NoVanishingPoints: return "no_vanishing_points";
  }
  return "no_vanishing_points";
}

std::vector<LineSegment> detect_lines(const cv::Mat& photo_linear, const LineDetectionOptions& options,
                                      StageReport& report) {
  const auto start = std::chrono::steady_clock::now();
  report.stage = "lines";
  std::vector<LineSegment> out;
  if (photo_linear.empty() || photo_linear.cols < 8 || photo_linear.rows < 8) {
    report.usable = false;
    report.why = "image too small for line detection";
    return out;
  }
  cv::Mat grey;
  cv::cvtColor(photo_linear, grey, cv::COLOR_RGB2GRAY);
  // LSD works on display-referred intensities: gamma-encode and scale to 8 bits.
  cv::Mat encoded;
  cv::pow(cv::max(grey, 0.0), 1.0 / 2.2, encoded);
  encoded.convertTo(encoded, CV_8U, 255.0);
  auto lsd = cv::createLineSegmentDetector(cv::LSD_REFINE_STD);
  std::vector<cv::Vec4f> raw;
  lsd->detect(encoded, raw);
  const double min_length = options.min_length_fraction * std::hypot(photo_linear.cols, photo_linear.rows);
  for (const auto& r : raw) {
    LineSegment l{{r[0] - 0.5, r[1] - 0.5}, {r[2] - 0.5, r[3] - 0.5}};  // LSD: pixel corners at integers
    if (l.length() >= min_length && l.a.allFinite() && l.b.allFinite()) out.push_back(l);
  }
  std::sort(out.begin(), out.end(), [](const auto& p, const auto& q) { return p.length() > q.length(); });
  if (static_cast<int>(out.size()) > options.max_lines) out.resize(options.max_lines);
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  report.usable = !out.empty();
  report.why = out.empty() ? "no line segments found" : std::to_string(out.size()) + " segments";
  report.details = {{"raw_segments", raw.size()}, {"kept", out.size()}};
  return out;
}

std::vector<LineSegment> read_lines_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open lines file '" + path + "'");
  std::vector<LineSegment> lines;
  std::string row;
  int line_number = 0;
  while (std::getline(in, row)) {
    ++line_number;
    if (row.find_first_not_of(" \t\r") == std::string::npos) continue;
    std::replace(row.begin(), row.end(), ',', ' ');
    std::istringstream fields(row);
    double v[4];
    if (!(fields >> v[0] >> v[1] >> v[2] >> v[3])) {
      if (line_number == 1) continue;  // header
      throw std::runtime_error(path + ":" + std::to_string(line_number) + ": expected x1,y1,x2,y2");
    }
    LineSegment l{{v[0], v[1]}, {v[2], v[3]}};
    if (l.a.allFinite() && l.b.allFinite() && l.length() > 0) lines.push_back(l);
  }
  return lines;
}

std::vector<LineSegment> read_lines_nyu(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open lines file '" + path + "'");
  std::string row;
  if (!std::getline(in, row)) throw std::runtime_error(path + ": empty file (expected a header)");
  // Column positions from the header.
  std::vector<std::string> names;
  {
    std::istringstream header(row);
    for (std::string name; header >> name;) names.push_back(name);
  }
  const auto column = [&](const char* name, bool required) {
    const auto it = std::find(names.begin(), names.end(), name);
    if (it == names.end()) {
      if (required) throw std::runtime_error(path + ": header has no column '" + name + "'");
      return -1;
    }
    return static_cast<int>(it - names.begin());
  };
  const int x1 = column("point1_x", true), y1 = column("point1_y", true), z1 = column("point1_z", false);
  const int x2 = column("point2_x", true), y2 = column("point2_y", true), z2 = column("point2_z", false);
  const int needed = std::max({x1, y1, z1, x2, y2, z2}) + 1;
  std::vector<LineSegment> lines;
  std::vector<double> v;
  int line_number = 1;
  while (std::getline(in, row)) {
    ++line_number;
    if (row.find_first_not_of(" \t\r") == std::string::npos) continue;
    std::istringstream fields(row);
    v.clear();
    for (double x; static_cast<int>(v.size()) < needed && fields >> x;) v.push_back(x);
    if (static_cast<int>(v.size()) < needed)
      throw std::runtime_error(path + ":" + std::to_string(line_number) + ": expected " + std::to_string(needed) +
                               " numbers");
    const double w1 = z1 >= 0 ? v[z1] : 1.0, w2 = z2 >= 0 ? v[z2] : 1.0;
    if (w1 == 0.0 || w2 == 0.0) continue;  // an endpoint at infinity is no segment
    LineSegment l{{v[x1] / w1, v[y1] / w1}, {v[x2] / w2, v[y2] / w2}};
    if (l.a.allFinite() && l.b.allFinite() && l.length() > 0) lines.push_back(l);
  }
  return lines;
}

CameraEstimate estimate_camera(const std::vector<LineSegment>& lines, int width, int height,
                               const CameraOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  if (width <= 0 || height <= 0) throw std::invalid_argument("estimate_camera: image size must be positive");
  CameraEstimate est;
  est.cx = (width - 1) / 2.0;
  est.cy = (height - 1) / 2.0;
  const double prior_f = options.prior_focal_px > 0 ? options.prior_focal_px : 0.85 * std::max(width, height);
  const double tolerance = std::sin(options.inlier_angle_deg * kDegToRad);

  // 1. Exhaustive focal hypotheses x RANSAC over minimal samples: two lines
  //    fix one direction, a third line fixes the second, the third follows.
  std::array<Vector3d, 3> best_dirs = {Vector3d::UnitX(), Vector3d::UnitY(), Vector3d::UnitZ()};
  double best_score = -1.0, best_f = prior_f;
  std::mt19937_64 rng(options.seed);
  if (lines.size() >= 3) {
    std::vector<double> weights;
    for (const auto& l : lines) weights.push_back(l.length());
    std::discrete_distribution<int> pick(weights.begin(), weights.end());
    const int hypotheses = std::max(1, options.focal_hypotheses);
    for (int h = 0; h < hypotheses; ++h) {
      const double t = hypotheses == 1 ? 0.5 : static_cast<double>(h) / (hypotheses - 1);
      const double f = prior_f * std::exp(std::log(0.4) + t * (std::log(2.5) - std::log(0.4)));
      const auto normals = interpretation_normals(lines, f, est.cx, est.cy);
      const double prior_penalty = 1.0 - kFocalPriorWeight * std::abs(std::log(f / prior_f));
      for (int it = 0; it < options.ransac_iterations; ++it) {
        const int i = pick(rng), j = pick(rng), k = pick(rng);
        if (i == j || i == k || j == k) continue;
        Vector3d d1 = normals[i].n.cross(normals[j].n);
        if (d1.norm() < kDegenerateCross) continue;
        d1.normalize();
        Vector3d d2 = d1.cross(normals[k].n);
        if (d2.norm() < kDegenerateCross) continue;
        d2.normalize();
        const std::array<Vector3d, 3> dirs = {d1, d2, d1.cross(d2).normalized()};
        const double score = score_frame(normals, dirs, tolerance) * prior_penalty;
        if (score > best_score) {
          best_score = score;
          best_dirs = dirs;
          best_f = f;
        }
      }
    }
  }

  // 2. Label lines, count support, decide which directions are real.
  auto normals = interpretation_normals(lines, best_f, est.cx, est.cy);
  std::vector<int> labels;
  std::array<double, 3> support{};
  score_frame(normals, best_dirs, tolerance, &support, &labels);
  std::array<int, 3> counts{};
  for (int l : labels)
    if (l >= 0) ++counts[l];
  int supported = 0;
  int finite_supported = 0;
  for (int k = 0; k < 3; ++k)
    if (counts[k] >= options.min_support_lines) {
      ++supported;
      if (std::abs(best_dirs[k].z()) > kFiniteVanishingZ) ++finite_supported;
    }

  // 3. Refine rotation (and focal length when two finite vanishing points
  //    constrain it) with bounded robust least squares.
  double focal = best_f;
  int refine_iterations = 0;
  bool refine_converged = false;
  double final_cost = 0.0;
  const bool refine_focal = supported == 3 && finite_supported >= 2;
  if (supported >= 2) {
    Matrix3d frame = frame_matrix(best_dirs);
    if (frame.determinant() < 0) frame.col(2) *= -1.0;
    double angle_axis[3];
    ceres::RotationMatrixToAngleAxis(frame.data(), angle_axis);
    double log_focal = std::log(refine_focal ? best_f : prior_f);
    ceres::Problem problem;
    for (size_t i = 0; i < lines.size(); ++i) {
      if (labels[i] < 0) continue;
      auto* cost = new ceres::AutoDiffCostFunction<LineDirectionResidual, 1, 3, 1>(
          new LineDirectionResidual(lines[i], est.cx, est.cy, labels[i], std::sqrt(lines[i].length())));
      problem.AddResidualBlock(cost, new ceres::CauchyLoss(tolerance * 4.0), angle_axis, &log_focal);
    }
    if (problem.NumResidualBlocks() > 0) {
      if (!refine_focal) problem.SetParameterBlockConstant(&log_focal);
      else {
        problem.SetParameterLowerBound(&log_focal, 0, std::log(prior_f * 0.3));
        problem.SetParameterUpperBound(&log_focal, 0, std::log(prior_f * 3.0));
      }
      ceres::Solver::Options solver;
      solver.max_num_iterations = options.max_refine_iterations;
      solver.max_solver_time_in_seconds = 2.0;
      solver.linear_solver_type = ceres::DENSE_QR;
      solver.num_threads = 1;
      ceres::Solver::Summary summary;
      ceres::Solve(solver, &problem, &summary);
      refine_iterations = static_cast<int>(summary.iterations.size());
      refine_converged = summary.termination_type == ceres::CONVERGENCE;
      final_cost = summary.final_cost;
      double refined[9];
      ceres::AngleAxisToRotationMatrix(angle_axis, refined);
      const Eigen::Map<Matrix3d> refined_frame(refined);
      if (refined_frame.allFinite() && std::isfinite(log_focal) && summary.IsSolutionUsable()) {
        for (int k = 0; k < 3; ++k) best_dirs[k] = refined_frame.col(k);
        focal = std::exp(log_focal);
      }
    }
  }
  if (!refine_focal) focal = prior_f;
  normals = interpretation_normals(lines, focal, est.cx, est.cy);
  score_frame(normals, best_dirs, tolerance, &support, &labels);
  counts = {};
  for (int l : labels)
    if (l >= 0) ++counts[l];

  // 4. Which direction is up: the supported one closest to the image's
  //    vertical axis (camera -y), if near enough. Otherwise a level camera.
  int up = -1;
  double best_vertical = std::cos(kMaxUpTiltDeg * kDegToRad);
  for (int k = 0; k < 3; ++k) {
    if (counts[k] < options.min_support_lines) continue;
    if (std::abs(best_dirs[k].y()) > best_vertical) {
      best_vertical = std::abs(best_dirs[k].y());
      up = k;
    }
  }
  Vector3d up_cam = up >= 0 ? best_dirs[up] : Vector3d(0, -1, 0);
  if (up_cam.y() > 0) up_cam = -up_cam;  // camera y points down
  // World Z: the supported horizontal direction closest to pointing back at the camera.
  Vector3d z_cam = Vector3d::Zero();
  double best_facing = -1.0;
  for (int k = 0; k < 3; ++k) {
    if (k == up || counts[k] < options.min_support_lines) continue;
    Vector3d d = best_dirs[k] - best_dirs[k].dot(up_cam) * up_cam;
    if (d.norm() < kDegenerateCross) continue;
    d.normalize();
    if (d.z() > 0) d = -d;
    if (-d.z() > best_facing) {
      best_facing = -d.z();
      z_cam = d;
    }
  }
  if (z_cam.isZero()) {
    // No horizontal vanishing direction: world Z is the camera's backward axis made level.
    z_cam = Vector3d(0, 0, -1) - Vector3d(0, 0, -1).dot(up_cam) * up_cam;
    if (z_cam.norm() < kDegenerateCross) z_cam = Vector3d(0, 1, 0) - Vector3d(0, 1, 0).dot(up_cam) * up_cam;
    z_cam.normalize();
  }
  const Vector3d x_cam = up_cam.cross(z_cam).normalized();
  // Columns of R_cam_from_world are the world axes in camera coordinates.
  Matrix3d R_cam_from_world;
  R_cam_from_world.col(0) = x_cam;
  R_cam_from_world.col(1) = up_cam;
  R_cam_from_world.col(2) = x_cam.cross(up_cam);
  est.R_world_from_cam = R_cam_from_world.transpose();
  est.directions_cam = {R_cam_from_world.col(0), R_cam_from_world.col(1), R_cam_from_world.col(2)};

  // Relabel lines against the final world axes.
  normals = interpretation_normals(lines, focal, est.cx, est.cy);
  score_frame(normals, est.directions_cam, tolerance, &est.support, &est.line_labels);
  std::array<int, 3> final_counts{};
  for (int l : est.line_labels)
    if (l >= 0) ++final_counts[l];
  const int horizontal_supported = (final_counts[0] >= options.min_support_lines) +
                                   (final_counts[2] >= options.min_support_lines);
  if (up < 0) est.which = CameraCase::NoVanishingPoints;
  else if (refine_focal && horizontal_supported == 2) est.which = CameraCase::ThreeVanishingPoints;
  else if (horizontal_supported >= 1) est.which = CameraCase::TwoVanishingPoints;
  else est.which = CameraCase::VerticalOnly;
  est.focal_from_vanishing_points = est.which == CameraCase::ThreeVanishingPoints;
  est.fx = est.fy = est.focal_from_vanishing_points ? focal : prior_f;

  StageReport& r = est.report;
  r.stage = "camera";
  r.usable = true;
  r.why = to_string(est.which);
  r.iterations = refine_iterations;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.details = {{"lines", lines.size()},
               {"inliers_per_axis", {final_counts[0], final_counts[1], final_counts[2]}},
               {"focal_px", est.fx},
               {"focal_prior_px", prior_f},
               {"refine_converged", refine_converged},
               {"refine_final_cost", final_cost}};
  if (!est.R_world_from_cam.allFinite() || !std::isfinite(est.fx)) {
    // Never hand on non-finite numbers: fall back to a level camera.
    est.R_world_from_cam = Matrix3d::Identity();
    est.R_world_from_cam(1, 1) = -1;
    est.R_world_from_cam(2, 2) = -1;
    est.fx = est.fy = prior_f;
    est.which = CameraCase::NoVanishingPoints;
    r.why = "non-finite estimate replaced by a level camera";
  }
  return est;
}

}  // namespace propcam::inference
