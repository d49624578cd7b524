#include "propcam/inference/camera.h"

#include <Eigen/Dense>
#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <random>
#include <sstream>

namespace propcam::inference {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr double kDegToRad = std::numbers::pi / 180.0;

// --- Lines ---
// Segments with an endpoint farther outside the frame than this share of its
// size are not image lines (absurd or corrupt coordinates): ignored.
constexpr double kMaxOutsideFraction = 0.5;
// Segments shorter than this share of the image diagonal are ignored, as the
// line stage does (detect_lines): a short segment fits almost any vanishing
// point (half of NYU-VP's LSD segments are shorter; they pulled vanishing
// points into clutter).
constexpr double kMinSegmentOfDiagonal = 0.025;
// ... and shorter than this many inlier tolerances (with a custom tolerance):
// a 2-tolerance segment fits every direction within 30 degrees.
constexpr double kMinSegmentOverTolerance = 5.0;
// The search uses at most this many (longest) segments; all are labelled.
constexpr int kMaxSearchLines = 400;
// Default inlier tolerance (endpoint distance): LSD endpoints on real photos
// are good to about a pixel; 2 px at 640x480, whose diagonal is 800 px.
constexpr double kInlierDistanceOfDiagonal = 0.0025;
// Floor for that tolerance on tiny images, pixels.
constexpr double kMinInlierDistancePx = 0.75;

// --- Vanishing-point candidates ---
// Homogeneous intersections shorter than this are degenerate (the two
// segments lie on one line).
constexpr double kDegenerateCross = 1e-9;
// Candidates closer than this (as directions at the prior focal length) are
// one vanishing point: a second copy is skipped.
constexpr double kCandidateSeparationDeg = 2.0;
// Greedy coverage counts a line as explained by a pick within this many
// squared tolerances (2x the distance): real edges (cloth, a distorted lens)
// scatter a little more than LSD's pixel, and copies of one vanishing point
// would otherwise fill the candidate list.
constexpr double kCoverageTolerance2 = 4.0;

// Knob ceilings, so that any options stay bounded in time (the defaults are
// 300, 12 and 11).
constexpr int kMaxSamples = 20000;
constexpr int kMaxCandidates = 40;
constexpr int kMaxFocalHypotheses = 25;

// --- Focal length ---
// Default focal prior: 0.85 x the longest side, a 60-degree horizontal view.
constexpr double kDefaultFocalOverSide = 0.85;
// Focal search range relative to the prior. With the default prior this
// spans horizontal fields of view of about 26 to 107 degrees.
constexpr double kMinFocalRatio = 0.4;
constexpr double kMaxFocalRatio = 2.5;
// Score penalty per unit |log(f / prior)|: breaks near-ties toward the prior.
constexpr double kFocalPriorWeight = 0.03;
// A direction with |z| below this has its vanishing point more than 6.6 focal
// lengths from the principal point and says little about the focal length
// (f from two vanishing points moves 3.4x a direction's angular error there).
constexpr double kFiniteVanishingZ = 0.15;
// The focal length comes from the lines only when all three directions are
// supported: two vanishing points fit some focal length whatever they are
// (f^2 = -p.q has no redundancy), the third checks them. On the hotel-room
// views, two-direction focal lengths were off by -28% to +144%.
constexpr int kMinDirectionsForFocal = 3;
// Line endpoints are taken to scatter by half the inlier tolerance (1 px at
// 640x480) ...
constexpr double kLineSigmaOfTolerance = 0.5;
// ... and the focal length is taken from the lines only when they fix log(f)
// to this standard deviation; otherwise the prior. On NYU-VP the real error
// runs ~1.5x this figure (distortion, principal point, labels), so 8% keeps
// focal lengths from lines near 10%.
constexpr double kMaxFocalLogStd = 0.08;
// When they do, a weak prior on log(f) is still added (25%: a phone or board
// lens is rarely further from the 60-degree default).
constexpr double kFocalPriorSigma = 0.25;

// --- Principal point ---
// Prior: the image centre, with this standard deviation as a share of the
// diagonal (lens-to-sensor offsets of phone and board cameras are about 1-2%
// of the diagonal; the Kinect's, in NYU-VP, is 1.9%). On NYU-VP a 3% prior
// let the estimate wander (p90 error 22 px against the centre's 15.5), 1.5%
// held it too close to the centre to help; 2% gave the lowest axis error.
constexpr double kCentrePriorOfDiagonal = 0.02;

// --- Frame ---
// A lone supported direction within this angle of the image's vertical axis
// is the vertical; otherwise it is horizontal.
constexpr double kMaxUpTiltDeg = 50.0;
// Label, refine, relabel: at most this many Ceres solves.
constexpr int kMaxRefineRounds = 3;

// A segment in normalised image coordinates: pixels relative to the
// principal point, divided by the prior focal length (so a vanishing point
// (x, y, w) is close to its 3D direction at the prior focal length).
struct Line {
  int index;      // in the caller's list
  Vector2d mid;   // midpoint
  Vector2d dir;   // unit direction
  double half;    // half length
  Vector3d hom;   // homogeneous line, (a, b) of unit length
  double weight;  // length in pixels
};

// Squared distance of the segment's endpoints from the line through its
// midpoint and the vanishing point v (homogeneous: finite or at infinity),
// in normalised units.
double endpoint_distance2(const Line& l, const Vector3d& v) {
  const double wx = v.x() - l.mid.x() * v.z(), wy = v.y() - l.mid.y() * v.z();
  const double w2 = wx * wx + wy * wy;
  if (!(w2 > 0.0)) return l.half * l.half;  // the vanishing point on the midpoint fixes no direction
  const double c = l.dir.x() * wy - l.dir.y() * wx;
  return l.half * l.half * c * c / w2;
}

// Soft vote of a line for a vanishing point: 1 on it, 0 at the tolerance.
double vote(const Line& l, const Vector3d& v, double tol2) { return 1.0 - endpoint_distance2(l, v) / tol2; }

// Length-weighted soft support of up to three vanishing points; each line
// votes for the one it fits best. Optionally the label (or -1) of each line.
double score_vps(const std::vector<Line>& lines, const Vector3d* vps, int n, double tol2,
                 std::vector<int>* labels = nullptr) {
  double total = 0.0;
  if (labels) labels->assign(lines.size(), -1);
  for (size_t i = 0; i < lines.size(); ++i) {
    double best = 0.0;
    int best_k = -1;
    for (int k = 0; k < n; ++k) {
      const double s = vote(lines[i], vps[k], tol2);
      if (s > best) {
        best = s;
        best_k = k;
      }
    }
    if (best_k < 0) continue;
    total += best * lines[i].weight;
    if (labels) (*labels)[i] = best_k;
  }
  return total;
}

// Vanishing point of a direction at focal length g (normalised units), and back.
Vector3d vp_of(const Vector3d& d, double g) { return {g * d.x(), g * d.y(), d.z()}; }
Vector3d direction_of(const Vector3d& v, double g) { return Vector3d(v.x() / g, v.y() / g, v.z()).normalized(); }

struct Frame {
  std::array<Vector3d, 3> d;  // orthonormal, right-handed
  double g = 1.0;             // focal length / prior
  Vector2d centre = Vector2d::Zero();  // principal point's offset from the image centre (normalised)
  double score = -1.0;
};

// The Manhattan frame whose first two axes are closest to the vanishing
// points va, vb at focal length g (the second is made orthogonal).
bool make_frame(const Vector3d& va, const Vector3d& vb, double g, Frame& f) {
  const Vector3d a = direction_of(va, g);
  Vector3d b = direction_of(vb, g);
  b -= a.dot(b) * a;
  if (!(b.norm() > 1e-6) || !a.allFinite()) return false;
  b.normalize();
  f.d = {a, b, a.cross(b)};
  f.g = g;
  return true;
}

// Vanishing point of direction d (camera) relative to the image centre, for a
// principal point offset by c from it.
Vector3d vp_of(const Vector3d& d, double g, const Vector2d& c) { return {g * d.x() + c.x() * d.z(), g * d.y() + c.y() * d.z(), d.z()}; }

std::array<Vector3d, 3> frame_vps(const Frame& f) {
  return {vp_of(f.d[0], f.g, f.centre), vp_of(f.d[1], f.g, f.centre), vp_of(f.d[2], f.g, f.centre)};
}

// The least-squares vanishing point of the lines that vote for v (smallest
// eigenvector of the weighted scatter of their homogeneous lines).
Vector3d refit_vp(const std::vector<Line>& lines, const Vector3d& v, double tol2) {
  Matrix3d scatter = Matrix3d::Zero();
  int inliers = 0;
  for (const auto& l : lines) {
    const double s = vote(l, v, tol2);
    if (s <= 0) continue;
    scatter += s * l.weight * l.hom * l.hom.transpose();
    ++inliers;
  }
  if (inliers < 3) return v;
  Eigen::SelfAdjointEigenSolver<Matrix3d> eig;
  eig.computeDirect(scatter);
  const Vector3d r = eig.eigenvectors().col(0);
  return r.allFinite() && r.norm() > 0.5 ? Vector3d(r.normalized()) : v;
}

// Residual of one inlier line: the signed distance (pixels) of its endpoint
// from the line through its midpoint and its axis' vanishing point.
// Parameters: the Manhattan frame's rotation (angle-axis) in camera
// coordinates, log(f / prior) and the principal point's offset from the
// image centre (normalised units; held at zero unless it is estimated).
struct EndpointResidual {
  EndpointResidual(const Line& l, int axis, double scale_px)
      : mx(l.mid.x()), my(l.mid.y()), tx(l.dir.x()), ty(l.dir.y()), half_px(l.half * scale_px), axis(axis) {}

  template <typename T>
  bool operator()(const T* const angle_axis, const T* const log_g, const T* const centre, T* residual) const {
    T unit_axis[3] = {T(0), T(0), T(0)};
    unit_axis[axis] = T(1);
    T d[3];
    ceres::AngleAxisRotatePoint(angle_axis, unit_axis, d);
    const T g = exp(log_g[0]);
    // The midpoint relative to the principal point.
    const T px = T(mx) - centre[0], py = T(my) - centre[1];
    const T wx = g * d[0] - px * d[2], wy = g * d[1] - py * d[2];
    // The floor keeps the derivative finite if a vanishing point crosses a midpoint.
    const T w = sqrt(wx * wx + wy * wy + T(1e-18));
    residual[0] = T(half_px) * (T(tx) * wy - T(ty) * wx) / w;
    return true;
  }
  double mx, my, tx, ty, half_px;
  int axis;
};

// Prior on the principal point's offset from the image centre, in the same
// units as the line residuals.
struct CentrePriorResidual {
  explicit CentrePriorResidual(double weight) : weight(weight) {}
  template <typename T>
  bool operator()(const T* const centre, T* residual) const {
    residual[0] = T(weight) * centre[0];
    residual[1] = T(weight) * centre[1];
    return true;
  }
  double weight;
};

// Weak prior on log(f / prior) in the same units as the line residuals.
struct FocalPriorResidual {
  explicit FocalPriorResidual(double weight) : weight(weight) {}
  template <typename T>
  bool operator()(const T* const log_g, T* residual) const {
    residual[0] = T(weight) * log_g[0];
    return true;
  }
  double weight;
};

using Matrix6d = Eigen::Matrix<double, 6, 6>;

// Gauss-Newton information (inverse covariance) that the labelled lines give
// about (rotation angle-axis, log f, principal-point offset): their robustly
// weighted endpoint residuals (noise sigma_px each), by central differences.
Matrix6d line_information(const std::vector<Line>& lines, const std::vector<int>& labels,
                          const std::array<bool, 3>& supported, const std::array<Vector3d, 3>& d, double g,
                          const Vector2d& centre, double scale_px, double sigma_px, double loss_px) {
  Matrix3d m;
  for (int k = 0; k < 3; ++k) m.col(k) = d[k];
  double p[6];
  ceres::RotationMatrixToAngleAxis(m.data(), p);
  p[3] = std::log(g);
  p[4] = centre.x();
  p[5] = centre.y();
  Matrix6d h = Matrix6d::Zero();
  constexpr double kStep = 1e-6;
  for (size_t i = 0; i < lines.size(); ++i) {
    if (labels[i] < 0 || !supported[labels[i]]) continue;
    const EndpointResidual f(lines[i], labels[i], scale_px);
    double r0;
    f(p, p + 3, p + 4, &r0);
    Eigen::Matrix<double, 6, 1> j;
    for (int c = 0; c < 6; ++c) {
      double q[6] = {p[0], p[1], p[2], p[3], p[4], p[5]}, rp, rm;
      q[c] += kStep;
      f(q, q + 3, q + 4, &rp);
      q[c] -= 2 * kStep;
      f(q, q + 3, q + 4, &rm);
      j[c] = (rp - rm) / (2 * kStep);
    }
    const double w = 1.0 / (1.0 + (r0 / loss_px) * (r0 / loss_px));  // Cauchy weight
    h += w * j * j.transpose();
  }
  return h / (sigma_px * sigma_px);
}

// Standard deviation of log(f) that the lines alone determine (principal
// point held fixed): the inverse of the information's first 4x4 block.
double focal_log_std(const Matrix6d& information) {
  const Eigen::Matrix4d h = information.topLeftCorner<4, 4>();
  const Eigen::FullPivLU<Eigen::Matrix4d> lu(h);
  if (!lu.isInvertible()) return std::numeric_limits<double>::infinity();
  const double var = lu.inverse()(3, 3);
  return var > 0 && std::isfinite(var) ? std::sqrt(var) : std::numeric_limits<double>::infinity();
}

// Largest standard deviation (normalised units) of the principal point
// given the lines plus the priors on log f and on the point itself.
double centre_std(Matrix6d information, double log_f_prior_sigma, double centre_prior_sigma) {
  information(3, 3) += 1.0 / (log_f_prior_sigma * log_f_prior_sigma);
  information(4, 4) += 1.0 / (centre_prior_sigma * centre_prior_sigma);
  information(5, 5) += 1.0 / (centre_prior_sigma * centre_prior_sigma);
  const Eigen::FullPivLU<Matrix6d> lu(information);
  if (!lu.isInvertible()) return std::numeric_limits<double>::infinity();
  const Eigen::Matrix2d cov = lu.inverse().bottomRightCorner<2, 2>();
  const double largest = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(cov).eigenvalues().maxCoeff();
  return largest > 0 && std::isfinite(largest) ? std::sqrt(largest) : std::numeric_limits<double>::infinity();
}

// The prior focal length and the tolerances every step measures with.
struct SearchScale {
  double prior_f = 0.0;             // pixels
  double tol_px = 0.0;              // inlier tolerance, pixels
  double tol2 = 0.0;                // squared tolerance, normalised units
  double centre_prior_sigma = 0.0;  // principal point prior, normalised units
  double g_min = 1.0, g_max = 1.0;  // focal search range over the prior
};

SearchScale search_scale(int width, int height, const CameraOptions& options) {
  SearchScale s;
  s.prior_f = options.prior_focal_px > 0 && std::isfinite(options.prior_focal_px)
                  ? options.prior_focal_px
                  : kDefaultFocalOverSide * std::max(width, height);
  s.tol_px = options.inlier_distance_px > 0 && std::isfinite(options.inlier_distance_px)
                 ? options.inlier_distance_px
                 : std::max(kMinInlierDistancePx, kInlierDistanceOfDiagonal * std::hypot(width, height));
  const double tol = s.tol_px / s.prior_f;  // normalised units
  s.tol2 = tol * tol;
  // Prior on the principal point (normalised units): the image centre.
  s.centre_prior_sigma = kCentrePriorOfDiagonal * std::hypot(width, height) / s.prior_f;
  s.g_min = options.fixed_focal ? 1.0 : kMinFocalRatio;
  s.g_max = options.fixed_focal ? 1.0 : kMaxFocalRatio;
  return s;
}

// 1. Usable segments, in normalised coordinates (pixels from the principal
//    point over the prior focal length).
std::vector<Line> usable_lines(const std::vector<LineSegment>& input, int width, int height, const Vector2d& centre,
                               const SearchScale& scale) {
  std::vector<Line> all;
  const double prior_f = scale.prior_f;
  const double ox = kMaxOutsideFraction * width, oy = kMaxOutsideFraction * height;
  const auto inside = [&](const Eigen::Vector2d& p) {
    return p.allFinite() && p.x() >= -ox && p.x() <= width - 1 + ox && p.y() >= -oy && p.y() <= height - 1 + oy;
  };
  const double min_length =
      std::max(kMinSegmentOfDiagonal * std::hypot(width, height), kMinSegmentOverTolerance * scale.tol_px);
  for (size_t i = 0; i < input.size(); ++i) {
    const LineSegment& s = input[i];
    if (!inside(s.a) || !inside(s.b) || !(s.length() >= min_length)) continue;
    const Vector2d a = (s.a - centre) / prior_f, b = (s.b - centre) / prior_f;
    Line l;
    l.index = static_cast<int>(i);
    l.mid = 0.5 * (a + b);
    l.dir = (b - a).normalized();
    l.half = 0.5 * (b - a).norm();
    l.hom = Vector3d(a.x(), a.y(), 1.0).cross(Vector3d(b.x(), b.y(), 1.0));
    l.hom /= l.hom.head<2>().norm();
    l.weight = s.length();
    all.push_back(l);
  }
  return all;
}

// The kMaxSearchLines longest lines (ties keep their order).
std::vector<Line> longest_lines(const std::vector<Line>& all) {
  std::vector<Line> search = all;
  std::stable_sort(search.begin(), search.end(), [](const Line& p, const Line& q) { return p.weight > q.weight; });
  if (search.size() > static_cast<size_t>(kMaxSearchLines)) search.resize(kMaxSearchLines);
  return search;
}

// A candidate's positive votes, sparse: (line, vote).
using Votes = std::vector<std::pair<int, double>>;

Votes positive_votes(const std::vector<Line>& search, const Vector3d& v, double tol2) {
  Votes out;
  for (size_t i = 0; i < search.size(); ++i) {
    const double s = vote(search[i], v, tol2);
    if (s > 0) out.emplace_back(static_cast<int>(i), s);
  }
  return out;
}

struct SampledCandidates {
  std::vector<Vector3d> candidates;
  std::vector<Votes> votes;  // per candidate
};

// 2. Vanishing-point candidates: intersections of length-weighted random
//    pairs of segments (homogeneous, so points at infinity are ordinary),
//    each with its soft, length-weighted support.
SampledCandidates sample_candidates(const std::vector<Line>& search, double tol2, const CameraOptions& options) {
  SampledCandidates out;
  if (search.size() < 2) return out;
  std::mt19937_64 rng(options.seed);
  std::vector<double> cumulative;
  double total = 0;
  for (const auto& l : search) cumulative.push_back(total += l.weight);
  std::uniform_real_distribution<double> u(0.0, total);
  const auto pick = [&] {
    const auto it = std::upper_bound(cumulative.begin(), cumulative.end(), u(rng));
    return std::min<size_t>(it - cumulative.begin(), search.size() - 1);
  };
  const int samples = std::clamp(options.ransac_iterations, 0, kMaxSamples);
  for (int it = 0; it < samples; ++it) {
    const size_t i = pick(), j = pick();
    if (i == j) continue;
    Vector3d v = search[i].hom.cross(search[j].hom);
    if (!(v.norm() > kDegenerateCross)) continue;
    v.normalize();
    out.candidates.push_back(v);
    out.votes.push_back(positive_votes(search, v, tol2));
  }
  return out;
}

// Greedy coverage: each pick is the candidate that explains the most line
// length not yet explained by earlier picks, so a second sample of the
// strongest vanishing point (or a blend of two) does not crowd out a
// weaker one; the pick is then refitted to its inliers. Up to
// `candidate_vps` distinct picks are kept.
std::vector<Vector3d> greedy_coverage(const std::vector<Line>& search, const SampledCandidates& sampled, double tol2,
                                      const CameraOptions& options) {
  std::vector<Vector3d> kept;
  if (search.size() < 2) return kept;
  const std::vector<Vector3d>& candidates = sampled.candidates;
  std::vector<double> covered(search.size(), 0.0);
  std::vector<char> used(candidates.size(), 0);
  const size_t want = static_cast<size_t>(std::clamp(options.candidate_vps, 0, kMaxCandidates));
  const double same = std::cos(kCandidateSeparationDeg * kDegToRad);
  while (kept.size() < want) {
    double best_gain = 0.0;
    int best_c = -1;
    for (size_t c = 0; c < candidates.size(); ++c) {
      if (used[c]) continue;
      double gain = 0.0;
      for (const auto& [i, s] : sampled.votes[c]) gain += std::max(0.0, s - covered[i]) * search[i].weight;
      if (gain > best_gain) {
        best_gain = gain;
        best_c = static_cast<int>(c);
      }
    }
    if (best_c < 0) break;
    used[best_c] = 1;
    const Vector3d v = refit_vp(search, candidates[best_c], tol2);
    const Vector3d dv = direction_of(v, 1.0);
    if (std::any_of(kept.begin(), kept.end(),
                    [&](const Vector3d& k) { return std::abs(direction_of(k, 1.0).dot(dv)) > same; }))
      continue;
    kept.push_back(v);
    // Lines near (not only within) the tolerance of a pick count as
    // explained: real edges (cloth, distortion) scatter a little more.
    for (size_t i = 0; i < search.size(); ++i)
      covered[i] = std::max(covered[i], vote(search[i], v, kCoverageTolerance2 * tol2));
  }
  return kept;
}

// Log-spaced focal hypotheses over the search range, the prior first.
std::vector<double> focal_grid(const CameraOptions& options, const SearchScale& scale) {
  std::vector<double> grid = {1.0};
  if (!options.fixed_focal)
    for (int h = 0, n = std::min(options.focal_hypotheses, kMaxFocalHypotheses); h < n && n > 1; ++h) {
      const double t = static_cast<double>(h) / (n - 1);
      const double g = std::exp(std::log(scale.g_min) + t * (std::log(scale.g_max) - std::log(scale.g_min)));
      if (std::abs(std::log(g)) > 1e-3) grid.push_back(g);  // the prior is already in
    }
  return grid;
}

// The best-scoring frame of those considered so far.
struct FrameSearch {
  FrameSearch(const std::vector<Line>& search, double tol2) : search(search), tol2(tol2) {}

  void consider(const Vector3d& va, const Vector3d& vb, double g) {
    Frame f;
    if (!make_frame(va, vb, g, f)) return;
    const auto vps = frame_vps(f);
    f.score = score_vps(search, vps.data(), 3, tol2) * (1.0 - kFocalPriorWeight * std::abs(std::log(g)));
    ++hypotheses;
    if (f.score > best.score) best = f;
  }

  const std::vector<Line>& search;
  const double tol2;
  Frame best;
  int hypotheses = 0;
};

// 3. Manhattan frames from pairs of candidates. Two finite vanishing points
//    of orthogonal directions fix the focal length (f^2 = -(p.q) for
//    points p, q relative to the principal point); the third direction is
//    their cross product. A pair with a point near infinity leaves f free:
//    then log-spaced focal hypotheses let the third direction's lines choose.
void search_frames(const std::vector<Vector3d>& kept, const std::vector<double>& focal_grid,
                   const CameraOptions& options, const SearchScale& scale, FrameSearch& frames) {
  const double g_min = scale.g_min, g_max = scale.g_max;
  for (size_t i = 0; i < kept.size(); ++i)
    for (size_t j = i + 1; j < kept.size(); ++j) {
      const Vector3d& a = kept[i];
      const Vector3d& b = kept[j];
      if (!options.fixed_focal) {
        const double g2 = -(a.x() * b.x() + a.y() * b.y()) / (a.z() * b.z());
        if (std::isfinite(g2) && g2 >= g_min * g_min && g2 <= g_max * g_max) {
          const double g = std::sqrt(g2);
          if (std::abs(direction_of(a, g).z()) >= kFiniteVanishingZ &&
              std::abs(direction_of(b, g).z()) >= kFiniteVanishingZ) {
            frames.consider(a, b, g);
            continue;
          }
        }
        const bool near_infinity = std::abs(direction_of(a, 1.0).z()) < kFiniteVanishingZ ||
                                   std::abs(direction_of(b, 1.0).z()) < kFiniteVanishingZ;
        if (!near_infinity) continue;  // two finite points that no focal length in range makes orthogonal
      }
      for (double g : focal_grid) frames.consider(a, b, g);
    }
  if (frames.best.score < 0 && !kept.empty()) {
    // A single candidate: its direction and the level direction orthogonal to it.
    const Vector3d a = direction_of(kept[0], 1.0);
    Vector3d b = Vector3d::UnitY() - a.y() * a;
    if (b.norm() < 1e-6) b = Vector3d::UnitX() - a.x() * a;
    frames.consider(kept[0], vp_of(b.normalized(), 1.0), 1.0);
  }
}

// 4. Refine: label the lines, then bounded robust least squares (Cauchy)
//    of their endpoint distances over the frame's rotation, and over the
//    focal length when the lines fix it (three supported directions, two
//    finite vanishing points, std of log f <= kMaxFocalLogStd; a weak prior
//    on it); relabel and repeat while the labels change.
class FrameRefiner {
 public:
  FrameRefiner(const std::vector<Line>& search, const SearchScale& scale, const CameraOptions& options,
               const Frame& best)
      : frame(best), have_frame(best.score >= 0), search_(search), scale_(scale), options_(options) {
    if (!have_frame) frame.d = {Vector3d::UnitX(), Vector3d::UnitY(), Vector3d::UnitZ()};
  }

  void refine() {
    std::vector<int> previous;
    bool previous_observable = false;
    for (int round = 0; have_frame && round < kMaxRefineRounds; ++round) {
      assess();
      if (round > 0 && labels == previous && observable == previous_observable) break;
      previous = labels;
      previous_observable = observable;
      if (!observable) frame.g = 1.0;
      if (supported_count == 0) break;
      solve(observable, false);
    }
    assess();
    if (!observable) frame.g = 1.0;
  }

  // 4b. Principal point: three vanishing points fix it (the orthocentre of
  //     their triangle) and two finite ones put it on their horizon, but it
  //     is the worst-conditioned part of the camera. So it is refined, with
  //     the prior at the image centre (MAP), only where the lines fixed the
  //     focal length. Returns the posterior deviation, pixels.
  double refine_principal_point() {
    solve(true, true);
    const Matrix6d info = line_information(search_, labels, supported, frame.d, frame.g, frame.centre, scale_.prior_f,
                                           kLineSigmaOfTolerance * scale_.tol_px, scale_.tol_px);
    return scale_.prior_f * centre_std(info, kFocalPriorSigma, scale_.centre_prior_sigma);
  }

  Frame frame;
  const bool have_frame;
  std::vector<int> labels;  // per search line: its axis or -1
  std::array<bool, 3> supported{};
  int supported_count = 0;
  bool observable = false;  // the lines fix the focal length
  double log_f_std = std::numeric_limits<double>::infinity();
  int iterations = 0, rounds = 0;
  bool converged = false;
  double final_cost = 0.0;

 private:
  // Labels the lines against the frame, and which axes they support.
  void assess() {
    const auto vps = frame_vps(frame);
    score_vps(search_, vps.data(), 3, scale_.tol2, &labels);
    std::array<int, 3> counts{};
    for (int l : labels)
      if (l >= 0) ++counts[l];
    supported_count = 0;
    int finite = 0;
    for (int k = 0; k < 3; ++k) {
      supported[k] = have_frame && counts[k] >= options_.min_support_lines;
      supported_count += supported[k];
      finite += supported[k] && std::abs(frame.d[k].z()) >= kFiniteVanishingZ;
    }
    observable = !options_.fixed_focal && supported_count >= kMinDirectionsForFocal && finite >= 2;
    log_f_std = observable ? focal_log_std(line_information(search_, labels, supported, frame.d, frame.g, frame.centre,
                                                            scale_.prior_f, kLineSigmaOfTolerance * scale_.tol_px,
                                                            scale_.tol_px))
                           : std::numeric_limits<double>::infinity();
    if (log_f_std > kMaxFocalLogStd) observable = false;
  }

  // The frame as Ceres' parameter blocks.
  struct Parameters {
    double angle_axis[3];
    double log_g;
    double centre[2];
  };

  // One bounded robust least-squares solve over the labelled lines: the
  // rotation always, log f and the principal point when asked.
  void solve(bool free_focal, bool free_centre) {
    Matrix3d m;
    for (int k = 0; k < 3; ++k) m.col(k) = frame.d[k];
    Parameters q;
    ceres::RotationMatrixToAngleAxis(m.data(), q.angle_axis);
    q.log_g = std::log(frame.g);
    q.centre[0] = frame.centre.x();
    q.centre[1] = frame.centre.y();
    ceres::CauchyLoss loss(scale_.tol_px);
    ceres::Problem::Options problem_options;
    problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(problem_options);
    for (size_t i = 0; i < search_.size(); ++i) {
      if (labels[i] < 0 || !supported[labels[i]]) continue;
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<EndpointResidual, 1, 3, 1, 2>(
                                   new EndpointResidual(search_[i], labels[i], scale_.prior_f)),
                               &loss, q.angle_axis, &q.log_g, q.centre);
    }
    free_or_hold_focal(problem, q, free_focal);
    free_or_hold_centre(problem, q, free_centre);
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options(), &problem, &summary);
    ++rounds;
    iterations += static_cast<int>(summary.iterations.size());
    converged = summary.termination_type == ceres::CONVERGENCE;
    final_cost = summary.final_cost;
    adopt_if_usable(q, summary);
  }

  // A free focal length has a weak prior and stays within the search range.
  void free_or_hold_focal(ceres::Problem& problem, Parameters& q, bool free_focal) const {
    if (!free_focal) {
      problem.SetParameterBlockConstant(&q.log_g);
      return;
    }
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<FocalPriorResidual, 1, 1>(
                                 new FocalPriorResidual(kLineSigmaOfTolerance * scale_.tol_px / kFocalPriorSigma)),
                             nullptr, &q.log_g);
    problem.SetParameterLowerBound(&q.log_g, 0, std::log(scale_.g_min));
    problem.SetParameterUpperBound(&q.log_g, 0, std::log(scale_.g_max));
  }

  // A free principal point has its prior at the image centre.
  void free_or_hold_centre(ceres::Problem& problem, Parameters& q, bool free_centre) const {
    if (!free_centre) {
      problem.SetParameterBlockConstant(q.centre);
      return;
    }
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<CentrePriorResidual, 2, 2>(new CentrePriorResidual(
                                 kLineSigmaOfTolerance * scale_.tol_px / scale_.centre_prior_sigma)),
                             nullptr, q.centre);
  }

  ceres::Solver::Options solver_options() const {
    ceres::Solver::Options solver;
    solver.max_num_iterations = options_.max_refine_iterations;
    solver.max_solver_time_in_seconds = options_.max_refine_seconds;
    solver.linear_solver_type = ceres::DENSE_QR;
    solver.num_threads = 1;
    return solver;
  }

  // The solved parameters become the frame only if they are finite and usable.
  void adopt_if_usable(const Parameters& q, const ceres::Solver::Summary& summary) {
    double refined[9];
    ceres::AngleAxisToRotationMatrix(q.angle_axis, refined);
    const Eigen::Map<Matrix3d> r(refined);
    const Vector2d c(q.centre[0], q.centre[1]);
    if (r.allFinite() && std::isfinite(q.log_g) && c.allFinite() && summary.IsSolutionUsable()) {
      for (int k = 0; k < 3; ++k) frame.d[k] = r.col(k);
      frame.g = std::exp(q.log_g);
      frame.centre = c;
    }
  }

  const std::vector<Line>& search_;
  const SearchScale& scale_;
  const CameraOptions& options_;
};

// 5. World axes. Up: with two or more supported directions the whole frame
//    is known and up is its axis nearest the image's vertical; a lone
//    direction near the vertical is up (yaw unknown); a lone horizontal one
//    gets the level up orthogonal to it (no roll); none: a level camera.
//    Sets est.which; returns up and a first guess at world Z (camera frame).
std::pair<Vector3d, Vector3d> up_and_back(const Frame& frame, const std::array<bool, 3>& supported,
                                          int supported_count, CameraEstimate& est) {
  Vector3d up_cam(0, -1, 0), z_cam = Vector3d::Zero();
  if (supported_count >= 2) {
    int up = 0;
    for (int k = 1; k < 3; ++k)
      if (std::abs(frame.d[k].y()) > std::abs(frame.d[up].y())) up = k;
    up_cam = frame.d[up];
    // World Z: the other axis nearest the optical axis (it will face the camera).
    for (int k = 0; k < 3; ++k)
      if (k != up && (z_cam.isZero() || std::abs(frame.d[k].z()) > std::abs(z_cam.z()))) z_cam = frame.d[k];
    est.which = supported_count == 3 ? CameraCase::ThreeVanishingPoints : CameraCase::TwoVanishingPoints;
  } else if (supported_count == 1) {
    const int k = supported[0] ? 0 : supported[1] ? 1 : 2;
    const Vector3d& d = frame.d[k];
    if (std::abs(d.y()) >= std::cos(kMaxUpTiltDeg * kDegToRad)) {
      up_cam = d;
      est.which = CameraCase::VerticalOnly;
    } else {
      up_cam = Vector3d(0, -1, 0) + d.y() * d;
      z_cam = d;
      est.which = CameraCase::HorizontalOnly;
    }
  } else {
    est.which = CameraCase::NoVanishingPoints;
  }
  return {up_cam, z_cam};
}

// Sets est.which, est.R_world_from_cam and est.directions_cam.
void set_world_axes(const Frame& frame, const std::array<bool, 3>& supported, int supported_count,
                    CameraEstimate& est) {
  auto [up_cam, z_cam] = up_and_back(frame, supported, supported_count, est);
  if (!(up_cam.norm() > 1e-9)) up_cam = Vector3d(0, -1, 0);
  up_cam.normalize();
  if (up_cam.y() > 0) up_cam = -up_cam;  // camera y points down
  z_cam -= z_cam.dot(up_cam) * up_cam;
  if (!(z_cam.norm() > 1e-6)) {
    // No horizontal vanishing direction: world Z is the camera's backward axis made level.
    z_cam = Vector3d(0, 0, -1) - Vector3d(0, 0, -1).dot(up_cam) * up_cam;
    if (z_cam.norm() < 1e-6) z_cam = Vector3d(0, 1, 0) - Vector3d(0, 1, 0).dot(up_cam) * up_cam;
  }
  z_cam.normalize();
  if (z_cam.z() > 0) z_cam = -z_cam;  // world Z points back at the camera
  const Vector3d x_cam = up_cam.cross(z_cam).normalized();
  // Columns of R_cam_from_world are the world axes in camera coordinates.
  Matrix3d R_cam_from_world;
  R_cam_from_world.col(0) = x_cam;
  R_cam_from_world.col(1) = up_cam;
  R_cam_from_world.col(2) = x_cam.cross(up_cam);
  est.R_world_from_cam = R_cam_from_world.transpose();
  est.directions_cam = {R_cam_from_world.col(0), R_cam_from_world.col(1), R_cam_from_world.col(2)};
}

// Labels every input line against the final world axes (est.line_labels,
// est.support); returns the inliers per axis.
std::array<int, 3> label_input_lines(const std::vector<Line>& all, size_t input_count, const SearchScale& scale,
                                     const Vector2d& centre, CameraEstimate& est) {
  const double g_final = est.fx / scale.prior_f;
  const std::array<Vector3d, 3> world_vps = {vp_of(est.directions_cam[0], g_final, centre),
                                             vp_of(est.directions_cam[1], g_final, centre),
                                             vp_of(est.directions_cam[2], g_final, centre)};
  std::vector<int> all_labels;
  score_vps(all, world_vps.data(), est.which == CameraCase::NoVanishingPoints ? 0 : 3, scale.tol2, &all_labels);
  est.line_labels.assign(input_count, -1);
  std::array<int, 3> final_counts{};
  est.support.fill(0.0);
  for (size_t i = 0; i < all.size(); ++i) {
    if (all_labels[i] < 0) continue;
    est.line_labels[all[i].index] = all_labels[i];
    ++final_counts[all_labels[i]];
    est.support[all_labels[i]] += all[i].weight;
  }
  return final_counts;
}

// What the search saw, for the report.
struct CameraSearchStats {
  size_t lines = 0, lines_used = 0, candidates = 0, distinct_candidates = 0;
  int frame_hypotheses = 0;
  std::array<int, 3> inliers_per_axis{};
};

nlohmann::json finite_or_null(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

StageReport camera_report(const CameraEstimate& est, const CameraSearchStats& stats, const SearchScale& scale,
                          const CameraOptions& options, const FrameRefiner& refiner, bool principal_estimated,
                          double principal_std_px, std::chrono::steady_clock::time_point start) {
  StageReport r;
  r.stage = "camera";
  r.usable = true;
  r.why = to_string(est.which);
  r.iterations = refiner.iterations;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const std::array<int, 3>& inliers = stats.inliers_per_axis;
  r.details = {{"lines", stats.lines},
               {"lines_used", stats.lines_used},
               {"candidates", static_cast<int>(stats.candidates)},
               {"distinct_candidates", stats.distinct_candidates},
               {"frame_hypotheses", stats.frame_hypotheses},
               {"inliers_per_axis", {inliers[0], inliers[1], inliers[2]}},
               {"inlier_distance_px", scale.tol_px},
               {"focal_px", est.fx},
               {"focal_prior_px", scale.prior_f},
               {"focal_prior_source", options.prior_focal_px > 0 && std::isfinite(options.prior_focal_px)
                                          ? (options.prior_source.empty() ? std::string("given") : options.prior_source)
                                          : std::string("default 60-degree lens")},
               {"focal_from_vanishing_points", est.focal_from_vanishing_points},
               {"focal_log_std", finite_or_null(refiner.log_f_std)},
               {"principal_point", {est.cx, est.cy}},
               {"principal_point_estimated", principal_estimated},
               {"principal_point_std_px", finite_or_null(principal_std_px)},
               {"refine_rounds", refiner.rounds},
               {"refine_converged", refiner.converged},
               {"refine_final_cost", refiner.final_cost}};
  return r;
}

// Never hand on non-finite numbers: fall back to a level camera.
void replace_with_level_camera(CameraEstimate& est, int width, int height, double prior_f, size_t input_count) {
  est.R_world_from_cam = Matrix3d::Identity();
  est.R_world_from_cam(1, 1) = -1;
  est.R_world_from_cam(2, 2) = -1;
  est.directions_cam = {Vector3d::UnitX(), Vector3d(0, -1, 0), Vector3d(0, 0, -1)};
  est.fx = est.fy = prior_f;
  est.cx = (width - 1) / 2.0;
  est.cy = (height - 1) / 2.0;
  est.which = CameraCase::NoVanishingPoints;
  est.focal_from_vanishing_points = false;
  est.line_labels.assign(input_count, -1);
  est.report.why = "non-finite estimate replaced by a level camera";
}

}  // namespace

const char* to_string(CameraCase c) {
  switch (c) {
    case CameraCase::ThreeVanishingPoints: return "three_vanishing_points";
    case CameraCase::TwoVanishingPoints: return "two_vanishing_points";
    case CameraCase::VerticalOnly: return "vertical_only";
    case CameraCase::HorizontalOnly: return "horizontal_only";
    case CameraCase::NoVanishingPoints: return "no_vanishing_points";
  }
  return "no_vanishing_points";
}

CameraEstimate estimate_camera(const std::vector<LineSegment>& input, int width, int height,
                               const CameraOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  if (width <= 0 || height <= 0) throw std::invalid_argument("estimate_camera: image size must be positive");
  CameraEstimate est;
  est.cx = (width - 1) / 2.0;
  est.cy = (height - 1) / 2.0;
  const SearchScale scale = search_scale(width, height, options);

  // 1. Usable segments; the longest of them drive the search.
  const std::vector<Line> all = usable_lines(input, width, height, Vector2d(est.cx, est.cy), scale);
  const std::vector<Line> search = longest_lines(all);
  // 2. Vanishing-point candidates.
  const SampledCandidates sampled = sample_candidates(search, scale.tol2, options);
  const std::vector<Vector3d> kept = greedy_coverage(search, sampled, scale.tol2, options);
  // 3. The best-scoring Manhattan frame from pairs of candidates.
  FrameSearch frames(search, scale.tol2);
  search_frames(kept, focal_grid(options, scale), options, scale, frames);
  // 4. Refine it on its labelled lines; 4b. the principal point where the lines allow.
  FrameRefiner refiner(search, scale, options, frames.best);
  refiner.refine();
  const bool principal_estimated = options.estimate_principal_point && refiner.observable && refiner.supported_count == 3;
  const double principal_std_px =
      principal_estimated ? refiner.refine_principal_point() : std::numeric_limits<double>::infinity();
  const Frame& frame = refiner.frame;
  est.cx += scale.prior_f * frame.centre.x();
  est.cy += scale.prior_f * frame.centre.y();
  const double focal = scale.prior_f * frame.g;
  // 5. World axes, the focal length, and every input line's label.
  set_world_axes(frame, refiner.supported, refiner.supported_count, est);
  est.focal_from_vanishing_points = refiner.observable;
  est.fx = est.fy = refiner.observable ? focal : scale.prior_f;
  const std::array<int, 3> final_counts = label_input_lines(all, input.size(), scale, frame.centre, est);

  const CameraSearchStats stats{input.size(), all.size(), sampled.candidates.size(), kept.size(), frames.hypotheses,
                                final_counts};
  est.report = camera_report(est, stats, scale, options, refiner, principal_estimated, principal_std_px, start);
  if (!est.R_world_from_cam.allFinite() || !std::isfinite(est.fx) || !(est.fx > 0) || !std::isfinite(est.cx) ||
      !std::isfinite(est.cy))
    replace_with_level_camera(est, width, height, scale.prior_f, input.size());
  return est;
}

}  // namespace propcam::inference
