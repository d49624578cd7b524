#include "propcam/inference/orientation_map.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <opencv2/imgproc.hpp>

namespace propcam::inference {
namespace {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;

constexpr double kInf = std::numeric_limits<double>::infinity();
// Output maps wider than this are a caller error (a 16k-wide label map is
// already far beyond what the depth solve's grid uses).
constexpr int kMaxOutputWidth = 16384;
// Segments with an endpoint further than this many frame sizes outside the
// frame are garbage (the camera stage ignores those beyond half a frame).
constexpr double kMaxOutsideFrames = 4.0;
// A homogeneous point whose |z| is below this fraction of its norm is taken
// as at infinity for distance limits (1e-12: only exact zeros and rounding).
constexpr double kInfinityZ = 1e-12;
// A sweep toward a finite vanishing point stops this short of it, where the
// band has collapsed to a sliver.
constexpr double kStopBeforeVanishingPoint = 0.98;
// Polygons are rasterised with this many fractional bits (1/16 px), so thin
// sweeps at 160 px wide still land on the right pixels.
constexpr int kSubpixelBits = 4;
// A sweep whose far edge cannot be placed (degenerate geometry) is retried
// this many times at half the distance before it is dropped.
constexpr int kSweepRetries = 4;
// The far corners of a sweep must stay within this many diagonals of the
// segment; beyond, the band is seen edge-on and the quad is meaningless.
constexpr double kMaxCornerDiagonals = 8.0;

struct Segment {
  Vec2 a, b;  // output pixels
  int axis;   // world direction of the line
};

Vec3 hom(const Vec2& p) { return {p.x(), p.y(), 1.0}; }

bool dehom(const Vec3& h, Vec2& p) {
  if (!h.allFinite() || std::abs(h.z()) <= kInfinityZ * h.norm()) return false;
  p = h.head<2>() / h.z();
  return p.allFinite();
}

// Unit image direction at p toward the homogeneous point v (for v at
// infinity, along it). Zero when p is v.
Vec2 direction_toward(const Vec3& v, const Vec2& p) {
  Vec2 d = v.head<2>() - p * v.z();
  if (v.z() < 0) d = -d;
  const double n = d.norm();
  return n > 0 && std::isfinite(n) ? Vec2(d / n) : Vec2::Zero();
}

void check_inputs(const std::vector<LineSegment>& lines, const std::vector<int>& labels,
                  const render::PinholeCamera& camera, const OrientationMapOptions& o) {
  if (lines.size() != labels.size())
    throw std::invalid_argument("estimate_orientation_map: " + std::to_string(lines.size()) + " lines but " +
                                std::to_string(labels.size()) + " line labels");
  if (o.width < 1 || o.width > kMaxOutputWidth)
    throw std::invalid_argument("estimate_orientation_map: options.width must be in [1, " +
                                std::to_string(kMaxOutputWidth) + "], got " + std::to_string(o.width));
  if (camera.width <= 0 || camera.height <= 0)
    throw std::invalid_argument("estimate_orientation_map: the camera has a non-positive image size");
  if (!(std::isfinite(camera.fx) && std::isfinite(camera.fy) && camera.fx > 0 && camera.fy > 0 &&
        std::isfinite(camera.cx) && std::isfinite(camera.cy) && camera.R_world_from_cam.allFinite()))
    throw std::invalid_argument("estimate_orientation_map: the camera's intrinsics or rotation are not finite/positive");
  for (double knob : {o.max_sweep_fraction, o.block_margin_fraction, o.end_inset_fraction,
                      o.min_sweep_length_fraction, o.min_sweep_angle_deg})
    if (!std::isfinite(knob) || knob < 0)
      throw std::invalid_argument("estimate_orientation_map: sweep options must be finite and non-negative");
}

// Lines in output pixels; non-finite, unlabelled or far-off segments dropped.
std::vector<Segment> usable_segments(const std::vector<LineSegment>& lines, const std::vector<int>& labels,
                                     const render::PinholeCamera& camera, int out_w, int out_h) {
  const double sx = static_cast<double>(out_w) / camera.width, sy = static_cast<double>(out_h) / camera.height;
  const double mx = kMaxOutsideFrames * camera.width, my = kMaxOutsideFrames * camera.height;
  auto sane = [&](const Vec2& p) {
    return p.allFinite() && p.x() > -mx && p.x() < camera.width + mx && p.y() > -my && p.y() < camera.height + my;
  };
  auto to_out = [&](const Vec2& p) { return Vec2((p.x() + 0.5) * sx - 0.5, (p.y() + 0.5) * sy - 0.5); };
  std::vector<Segment> out;
  for (size_t n = 0; n < lines.size(); ++n) {
    if (labels[n] < 0 || labels[n] > 2) continue;
    if (!sane(lines[n].a) || !sane(lines[n].b)) continue;
    const Segment s{to_out(lines[n].a), to_out(lines[n].b), labels[n]};
    if ((s.b - s.a).norm() > 0) out.push_back(s);
  }
  return out;
}

// Vanishing point of each world axis at the output resolution (homogeneous, unit norm).
std::array<Vec3, 3> vanishing_points(const render::PinholeCamera& out_camera) {
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();
  K(0, 0) = out_camera.fx;
  K(1, 1) = out_camera.fy;
  K(0, 2) = out_camera.cx;
  K(1, 2) = out_camera.cy;
  std::array<Vec3, 3> vp;
  for (int a = 0; a < 3; ++a) {
    const Vec3 v = K * (out_camera.R_world_from_cam.transpose() * Vec3::Unit(a));
    vp[a] = v / v.norm();
  }
  return vp;
}

// One sweep: a segment of class i moved along the pencil of lines through
// VP_j (its ends slide on the lines `edge_a`, `edge_b` through VP_j) while it
// keeps pointing at VP_i (the moving front is a line through VP_i).
struct Sweep {
  Vec2 a, b, m;        // segment ends and midpoint
  Vec3 vp_i, vp_j;     // homogeneous
  Vec3 edge_a, edge_b; // lines through VP_j and the (inset) ends, for blocking
  Vec3 edge_a_full, edge_b_full;  // through the true ends, for painting
  Vec3 mid_line;       // through VP_j and the midpoint: the sweep's axis
  Vec2 dir;            // unit direction of travel of the midpoint
  double side_a = 0, side_b = 0;  // signs of the inside of the band for edge_a, edge_b

  // Travel of the front through x, measured at the midpoint along `dir`;
  // +inf when the front through x never meets the axis.
  double travel(const Vec2& x) const {
    Vec2 q;
    if (!dehom(vp_i.cross(hom(x)).cross(mid_line), q)) return kInf;
    return (q - m).dot(dir);
  }
  // Where the front at travel t meets an edge line.
  bool front_corner(double t, const Vec3& edge, Vec2& corner) const {
    const Vec3 front = vp_i.cross(hom(m + t * dir));
    return dehom(front.cross(edge), corner);
  }
};

// Clips segment p0-p1 to the half-plane sign * (line . x) >= 0. False when nothing is left.
bool clip_half_plane(const Vec3& line, double sign, Vec2& p0, Vec2& p1) {
  const double f0 = sign * line.dot(hom(p0)), f1 = sign * line.dot(hom(p1));
  if (f0 < 0 && f1 < 0) return false;
  if (f0 >= 0 && f1 >= 0) return true;
  const Vec2 cut = p0 + (f0 / (f0 - f1)) * (p1 - p0);
  (f0 < 0 ? p0 : p1) = cut;
  return true;
}

// Smallest travel >= margin at which the front reaches blocker q0-q1 inside
// the band; +inf when it never does. Travel along a straight blocker is a
// projective function of position: monotone except across one pole, where
// the blocker is split.
double blocker_travel(const Sweep& s, Vec2 q0, Vec2 q1, double margin, bool ahead_only) {
  if (!clip_half_plane(s.edge_a, s.side_a, q0, q1) || !clip_half_plane(s.edge_b, s.side_b, q0, q1)) return kInf;
  // Denominator of the travel (z of the meeting point) is affine in the blocker parameter.
  const Vec3 h0 = s.vp_i.cross(hom(q0)).cross(s.mid_line), h1 = s.vp_i.cross(hom(q1)).cross(s.mid_line);
  std::array<std::pair<Vec2, Vec2>, 2> pieces{{{q0, q1}, {q1, q1}}};
  int count = 1;
  if ((h0.z() < 0) != (h1.z() < 0)) {
    constexpr double kPoleGap = 1e-6;  // fraction of the blocker skipped on each side of the pole
    const double u = h0.z() / (h0.z() - h1.z());
    pieces[0] = {q0, q0 + std::max(0.0, u - kPoleGap) * (q1 - q0)};
    pieces[1] = {q0 + std::min(1.0, u + kPoleGap) * (q1 - q0), q1};
    count = 2;
  }
  double best = kInf, lowest = kInf;
  for (int p = 0; p < count; ++p) {
    double t0 = s.travel(pieces[p].first), t1 = s.travel(pieces[p].second);
    if (t0 > t1) std::swap(t0, t1);
    lowest = std::min(lowest, t0);
    if (t1 >= margin) best = std::min(best, std::max(t0, margin));
  }
  if (ahead_only && lowest <= margin) return kInf;
  return best;
}

struct SweepLimits {
  double max_travel_px;   // bound on the sweep
  double margin_px;       // blockers must reach this far in
  double inset;           // fraction of the segment removed at each end for blocking
  double max_corner_px;   // far corners beyond this are degenerate
};

// Builds the sweep of `seg` toward (side +1) or away from (side -1) VP_j.
// False when the segment points at VP_j (nothing to sweep).
bool make_sweep(const Segment& seg, const Vec3& vp_i, const Vec3& vp_j, int side, double inset, Sweep& s) {
  s.a = seg.a;
  s.b = seg.b;
  s.m = 0.5 * (seg.a + seg.b);
  s.vp_i = vp_i;
  s.vp_j = vp_j;
  s.dir = side * direction_toward(vp_j, s.m);
  if (s.dir.isZero()) return false;
  const Vec2 ia = seg.a + inset * (seg.b - seg.a), ib = seg.b - inset * (seg.b - seg.a);
  s.edge_a = hom(ia).cross(vp_j);
  s.edge_b = hom(ib).cross(vp_j);
  s.edge_a_full = hom(seg.a).cross(vp_j);
  s.edge_b_full = hom(seg.b).cross(vp_j);
  s.mid_line = hom(s.m).cross(vp_j);
  s.side_a = s.edge_a.dot(hom(ib)) >= 0 ? 1.0 : -1.0;
  s.side_b = s.edge_b.dot(hom(ia)) >= 0 ? 1.0 : -1.0;
  return s.mid_line.head<2>().norm() > 0;
}

// Longest travel before the sweep leaves its bound or reaches VP_j.
double travel_bound(const Sweep& s, const SweepLimits& lim) {
  double bound = lim.max_travel_px;
  Vec2 vp;
  if (dehom(s.vp_j, vp) && (vp - s.m).dot(s.dir) > 0)
    bound = std::min(bound, kStopBeforeVanishingPoint * (vp - s.m).norm());
  return bound;
}

// Paints the quad swept up to travel t; halves t while its far corners are degenerate.
void paint_sweep(const Sweep& s, double t, double max_corner_px, cv::Mat& mask) {
  for (int attempt = 0; attempt <= kSweepRetries && t > 0; ++attempt, t *= 0.5) {
    Vec2 fa, fb;
    if (!s.front_corner(t, s.edge_a_full, fa) || !s.front_corner(t, s.edge_b_full, fb)) continue;
    // The far corners must lie ahead of the segment's ends, and not absurdly far.
    if ((fa - s.a).dot(s.dir) <= 0 || (fb - s.b).dot(s.dir) <= 0) continue;
    if ((fa - s.a).norm() > max_corner_px || (fb - s.b).norm() > max_corner_px) continue;
    // Clip to the frame (plus a pixel) in double so the fixed-point corners stay small.
    std::vector<Vec2> poly{s.a, s.b, fb, fa};
    const double x_max = mask.cols, y_max = mask.rows;
    const std::array<Vec3, 4> borders{Vec3(1, 0, 1), Vec3(-1, 0, x_max), Vec3(0, 1, 1), Vec3(0, -1, y_max)};
    for (const Vec3& border : borders) {
      std::vector<Vec2> kept;
      for (size_t n = 0; n < poly.size(); ++n) {
        const Vec2 &p = poly[n], &q = poly[(n + 1) % poly.size()];
        const double fp = border.dot(hom(p)), fq = border.dot(hom(q));
        if (fp >= 0) kept.push_back(p);
        if ((fp >= 0) != (fq >= 0)) kept.push_back(p + (fp / (fp - fq)) * (q - p));
      }
      poly.swap(kept);
    }
    if (poly.size() < 3) return;
    std::vector<cv::Point> pts;
    constexpr double kScale = 1 << kSubpixelBits;
    for (const Vec2& p : poly) pts.emplace_back(cvRound(p.x() * kScale), cvRound(p.y() * kScale));
    cv::fillConvexPoly(mask, pts, cv::Scalar(255), cv::LINE_8, kSubpixelBits);
    return;
  }
}

int third_axis(int i, int j) { return 3 - i - j; }

}  // namespace

OrientationMap estimate_orientation_map(const std::vector<LineSegment>& lines, const std::vector<int>& line_labels,
                                        const render::PinholeCamera& camera, const OrientationMapOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  check_inputs(lines, line_labels, camera, options);
  const int out_w = options.width;
  const int out_h = std::max(1, static_cast<int>(std::lround(static_cast<double>(out_w) * camera.height / camera.width)));
  const render::PinholeCamera out_camera = camera.resized(out_w, out_h);
  const std::vector<Segment> segments = usable_segments(lines, line_labels, camera, out_w, out_h);
  const std::array<Vec3, 3> vp = vanishing_points(out_camera);

  const double diagonal = std::hypot(out_w, out_h);
  const SweepLimits limits{options.max_sweep_fraction * diagonal, options.block_margin_fraction * diagonal,
                           std::min(options.end_inset_fraction, 0.45), kMaxCornerDiagonals * diagonal};
  const double min_length = options.min_sweep_length_fraction * diagonal;
  const double min_angle_cos = std::cos(options.min_sweep_angle_deg * std::numbers::pi / 180.0);

  std::array<std::vector<const Segment*>, 3> by_axis;
  for (const Segment& s : segments) by_axis[s.axis].push_back(&s);

  // support[i][j]: pixels swept by lines of class i toward/away from VP_j.
  std::array<std::array<cv::Mat, 3>, 3> support;
  int swept_lines = 0;
  for (int i = 0; i < 3; ++i) {
    for (const Segment* seg : by_axis[i]) {
      const Vec2 along = seg->b - seg->a;
      const double length = along.norm();
      if (length < min_length) continue;
      bool swept = false;
      for (int j = 0; j < 3; ++j) {
        if (j == i) continue;
        // A segment that points at VP_j would only slide along itself.
        const Vec2 m = 0.5 * (seg->a + seg->b);
        if (std::abs(direction_toward(vp[j], m).dot(along / length)) > min_angle_cos) continue;
        cv::Mat& mask = support[i][j];
        if (mask.empty()) mask = cv::Mat::zeros(out_h, out_w, CV_8U);
        const auto& blockers = by_axis[third_axis(i, j)];
        for (int side : {+1, -1}) {
          Sweep s;
          if (!make_sweep(*seg, vp[i], vp[j], side, limits.inset, s)) continue;
          double reach = travel_bound(s, limits);
          for (const Segment* blocker : blockers)
            reach = std::min(reach, blocker_travel(s, blocker->a, blocker->b, limits.margin_px, false));
          if (options.block_by_lines_ahead)
            for (const Segment* blocker : by_axis[j])
              reach = std::min(reach, blocker_travel(s, blocker->a, blocker->b, limits.margin_px, true));
          // Blocked at the start: nothing was swept (painting the sliver would put
          // conflicting support on the segment's own pixels).
          if (reach > limits.margin_px) paint_sweep(s, reach, limits.max_corner_px, mask);
          swept = true;
        }
      }
      swept_lines += swept ? 1 : 0;
    }
  }

  OrientationMap out;
  out.labels = cv::Mat::zeros(out_h, out_w, CV_8U);
  std::array<cv::Mat, 3> orientation_support;
  for (int k = 0; k < 3; ++k) {
    const int i = (k + 1) % 3, j = (k + 2) % 3;
    if (!support[i][j].empty() && !support[j][i].empty())
      cv::bitwise_and(support[i][j], support[j][i], orientation_support[k]);
  }
  std::array<int, 4> counts{};
  for (int y = 0; y < out_h; ++y) {
    uint8_t* row = out.labels.ptr<uint8_t>(y);
    for (int x = 0; x < out_w; ++x) {
      int label = 0, votes = 0;
      for (int k = 0; k < 3; ++k)
        if (!orientation_support[k].empty() && orientation_support[k].at<uint8_t>(y, x)) {
          label = k + 1;
          ++votes;
        }
      row[x] = static_cast<uint8_t>(votes == 1 ? label : 0);
      ++counts[row[x]];
    }
  }

  // Horizontal surfaces above the horizon are ceilings, below it floors:
  // a seen ceiling is the scene-class stage's sign of a room.
  int ceiling = 0, floor = 0;
  const double to_full_x = static_cast<double>(camera.width) / out_w, to_full_y = static_cast<double>(camera.height) / out_h;
  for (int y = 0; y < out_h; ++y)
    for (int x = 0; x < out_w; ++x)
      if (out.labels.at<uint8_t>(y, x) == static_cast<uint8_t>(SurfaceOrientation::kNormalY)) {
        const double up = camera.ray_direction((x + 0.5) * to_full_x - 0.5, (y + 0.5) * to_full_y - 0.5).y();
        (up > 0 ? ceiling : floor) += 1;
      }
  const double total = static_cast<double>(out_w) * out_h;
  StageReport& r = out.report;
  r.stage = "orientation_map";
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double coverage = (total - counts[0]) / total;
  r.usable = coverage > 0;
  r.why = r.usable ? "line sweeps" : "no pixel covered by sweeps of two line classes";
  r.iterations = swept_lines;
  r.details = {{"coverage", coverage},
               {"fraction_x", counts[1] / total},
               {"fraction_y", counts[2] / total},
               {"fraction_z", counts[3] / total},
               {"ceiling_fraction", ceiling / total},
               {"floor_fraction", floor / total},
               {"lines_used", swept_lines},
               {"lines_labelled", static_cast<int>(segments.size())},
               {"width", out_w},
               {"height", out_h},
               {"seconds", r.seconds}};
  return out;
}

cv::Mat orientation_map_to_color(const cv::Mat& labels) {
  if (labels.type() != CV_8U) throw std::invalid_argument("orientation_map_to_color: labels must be CV_8U");
  static const std::array<cv::Vec3b, 4> kColours{cv::Vec3b(0, 0, 0), cv::Vec3b(255, 0, 0), cv::Vec3b(0, 255, 0),
                                                 cv::Vec3b(0, 0, 255)};  // RGB: unknown, X, Y, Z
  cv::Mat out(labels.size(), CV_8UC3);
  for (int y = 0; y < labels.rows; ++y)
    for (int x = 0; x < labels.cols; ++x) {
      const uint8_t l = labels.at<uint8_t>(y, x);
      out.at<cv::Vec3b>(y, x) = l < kColours.size() ? kColours[l] : cv::Vec3b(0, 0, 0);
    }
  return out;
}

}  // namespace propcam::inference
