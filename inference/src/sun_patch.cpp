#include "propcam/inference/sun_patch.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <tuple>

#include "depth_samples.h"
#include "luminance.h"
#include "propcam/inference/orientation_map.h"
#include "propcam/render/depth_mesh.h"

namespace propcam::inference {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr double kDegree = std::numbers::pi / 180.0;
// The outline's shear is searched in steps of this.
constexpr double kShearStepDeg = 1.0;
// Outlines whose areas differ by less than this share fit equally well (a
// rectangle fits along either wall).
constexpr double kSameFitShare = 0.03;
// Below this luminance the floor is black: no ratio means anything.
constexpr double kMinLuminance = 1e-4;
// Where the window would be in the frame, the depth seen there is either
// well past it (nothing stands there: no window), about at it (its wall is
// seen: the window would show), or nearer (something hides it).
constexpr double kSeenPastShare = 1.25, kHiddenShare = 0.8;
// A window point this close to the camera's plane (m) is behind it.
constexpr double kMinViewDepthM = 0.1;
// The ring needs this many floor pixels to judge the patch's edge.
constexpr int kMinRingPixels = 12;

// The floor the photo sees: a mask and each pixel's floor point (x, z).
struct FloorMap {
  cv::Mat mask;  // CV_8U
  cv::Mat xz;    // CV_32FC2
  int count = 0;
};

// Whether the orientation map calls pixel (x, y) of a w x h image a wall.
bool on_wall(const cv::Mat& orientation, int x, int y, int w, int h) {
  if (orientation.empty() || orientation.type() != CV_8U) return false;
  const uint8_t label = orientation.at<uint8_t>(y * orientation.rows / h, x * orientation.cols / w);
  return label == static_cast<uint8_t>(SurfaceOrientation::kNormalX) ||
         label == static_cast<uint8_t>(SurfaceOrientation::kNormalZ);
}

FloorMap floor_map(const cv::Mat& depth, const render::PinholeCamera& camera, double floor_y,
                   const cv::Mat& orientation, const SunPatchOptions& options) {
  FloorMap f{cv::Mat::zeros(depth.size(), CV_8U), cv::Mat::zeros(depth.size(), CV_32FC2)};
  for (int y = 0; y < depth.rows; ++y)
    for (int x = 0; x < depth.cols; ++x) {
      if (on_wall(orientation, x, y, depth.cols, depth.rows)) continue;
      const float d = depth.at<float>(y, x);
      if (!depth_samples::is_surface(d)) continue;
      const Vector3d p = depth_samples::world_point(camera, x, y, d);
      if (!p.allFinite() || !(std::abs(p.y() - floor_y) < options.max_floor_height_m)) continue;
      f.mask.at<uint8_t>(y, x) = 255;
      f.xz.at<cv::Vec2f>(y, x) = {static_cast<float>(p.x()), static_cast<float>(p.z())};
      ++f.count;
    }
  return f;
}

double percentile_on(const cv::Mat& values, const cv::Mat& mask, double q) {
  std::vector<double> v;
  for (int y = 0; y < values.rows; ++y)
    for (int x = 0; x < values.cols; ++x)
      if (mask.at<uint8_t>(y, x) && std::isfinite(values.at<float>(y, x))) v.push_back(values.at<float>(y, x));
  return v.empty() ? 0.0 : depth_samples::percentile(std::move(v), q);
}

double mean_on(const cv::Mat& values, const cv::Mat& mask) {
  double sum = 0;
  int n = 0;
  for (int y = 0; y < values.rows; ++y)
    for (int x = 0; x < values.cols; ++x)
      if (mask.at<uint8_t>(y, x) && std::isfinite(values.at<float>(y, x))) sum += values.at<float>(y, x), ++n;
  return n > 0 ? sum / n : 0.0;
}

// The outline: the least parallelogram around the patch's floor points with
// one pair of sides along a wall (a world axis) and the other turned from
// the wall's normal by `shear`.
struct Outline {
  Vector2d wall, sun_line;  // unit, in (x, z)
  double a0 = 0, a1 = 0, b0 = 0, b1 = 0;  // extents along wall and sun_line
  double area = 0, shear_deg = 0;
  int wall_axis = 0;  // 0: x, 1: z
};

Outline fit_outline(const std::vector<cv::Point2f>& hull, int wall_axis, const SunPatchOptions& options) {
  const Vector2d w = wall_axis == 0 ? Vector2d(1, 0) : Vector2d(0, 1);
  const Vector2d n(-w.y(), w.x());
  Outline best;
  best.area = std::numeric_limits<double>::infinity();
  const int steps = static_cast<int>(std::floor(options.max_shear_deg / kShearStepDeg));
  for (int i = -steps; i <= steps; ++i) {
    const double shear = i * kShearStepDeg * kDegree;
    const Vector2d a = std::cos(shear) * n + std::sin(shear) * w;
    Outline o{w, a};
    o.a0 = o.b0 = std::numeric_limits<double>::infinity();
    o.a1 = o.b1 = -std::numeric_limits<double>::infinity();
    for (const cv::Point2f& q : hull) {
      const Vector2d p(q.x, q.y);
      // p = alpha * w + beta * a
      const double beta = p.dot(n) / std::cos(shear), alpha = p.dot(w) - beta * std::sin(shear);
      o.a0 = std::min(o.a0, alpha), o.a1 = std::max(o.a1, alpha);
      o.b0 = std::min(o.b0, beta), o.b1 = std::max(o.b1, beta);
    }
    o.area = (o.a1 - o.a0) * (o.b1 - o.b0) * std::cos(shear);
    o.shear_deg = i * kShearStepDeg;
    o.wall_axis = wall_axis;
    if (o.area < best.area) best = o;
  }
  return best;
}

// One reading of the outline: the sun along +-sun_line at an elevation.
struct SunHypothesis {
  Outline outline;
  Vector3d direction;
  int seen = 0;        // +1 the window would show and the photo is bright there, -1 it contradicts the photo
  double behind = 0;   // how far behind the camera the sun's azimuth points
};

Vector3d floor_point(const Vector2d& xz, double floor_y) { return {xz.x(), floor_y, xz.y()}; }

// Would the window this sun comes through show in the photo, and does it?
int window_evidence(const Vector3d& window_centre, const cv::Mat& depth, const cv::Mat& luminance,
                    double bright_level, const render::PinholeCamera& camera) {
  const auto at = depth_samples::seen_at(camera, depth, window_centre, kMinViewDepthM);
  if (!at) return 0;  // behind the camera or out of the frame
  const double seen = at->seen_depth;
  if (!(seen >= kHiddenShare * at->point_depth)) return 0;  // something nearer hides it
  if (seen > kSeenPastShare * at->point_depth && seen < render::kSkyDepthM) return -1;  // the photo sees past it: no wall there
  return luminance.at<float>(at->pixel) >= bright_level ? 1 : -1;
}

}  // namespace

SunPatch find_sun_patch(const cv::Mat& photo_linear, const cv::Mat& depth, const render::PinholeCamera& camera,
                        const RoomHeights& heights, const SunPatchOptions& options, const cv::Mat& orientation) {
  SunPatch out;
  auto not_found = [&](std::string why) {
    out.why = std::move(why);
    out.mask = cv::Mat();
    out.ring = cv::Mat();
    return out;
  };
  if (photo_linear.empty() || photo_linear.type() != CV_32FC3 || depth.type() != CV_32F ||
      depth.size() != photo_linear.size())
    return not_found("no photo and depth of one size");
  const double floor_y = heights.floor_y.value_or(0.0);
  const FloorMap floor = floor_map(depth, camera, floor_y, orientation, options);
  const double pixels = static_cast<double>(photo_linear.total());
  out.details["floor_share"] = floor.count / pixels;
  if (floor.count < options.min_floor_share * pixels) return not_found("too little floor seen");

  // Bright floor regions, well above the unlit floor's level.
  const cv::Mat lum = luminance_image(photo_linear);
  const double reference = std::max(kMinLuminance, percentile_on(lum, floor.mask, options.reference_percentile));
  out.details["floor_reference"] = reference;
  cv::Mat bright = (lum >= options.min_brightness_ratio * reference) & floor.mask;
  cv::morphologyEx(bright, bright, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_ELLIPSE, {3, 3}));
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(bright, labels, stats, centroids, 8, CV_32S);
  const double min_area = std::max(4.0, options.min_area_share * pixels);
  int regions = 0, largest = 0, largest_area = 0;
  for (int i = 1; i < n; ++i) {
    const int area = stats.at<int>(i, cv::CC_STAT_AREA);
    if (area < min_area) continue;
    ++regions;
    if (area > largest_area) largest_area = area, largest = i;
  }
  out.details["bright_regions"] = regions;
  if (regions == 0) return not_found("no bright patch on the floor");
  if (regions > options.max_bright_regions)
    return not_found(std::to_string(regions) + " bright floor regions: a pattern, not light through an opening");
  out.mask = labels == largest;

  // A sharp edge: the patch against the floor just outside it.
  const int ring_px = std::max(2, static_cast<int>(std::lround(options.ring_width_share * photo_linear.cols)));
  cv::Mat grown, all_bright;
  cv::dilate(out.mask, grown, cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * ring_px + 1, 2 * ring_px + 1}));
  cv::dilate(bright, all_bright, cv::getStructuringElement(cv::MORPH_ELLIPSE, {3, 3}));
  out.ring = grown & ~all_bright & floor.mask;
  if (cv::countNonZero(out.ring) < kMinRingPixels) return not_found("no floor around the patch to judge its edge");
  const double around = std::max(kMinLuminance, mean_on(lum, out.ring));
  out.brightness_ratio = mean_on(lum, out.mask) / around;
  out.details["brightness_ratio"] = out.brightness_ratio;
  // The band just inside the edge against the ring just outside: a lamp's
  // pool is barely brighter inside its threshold than outside it.
  cv::Mat shrunk;
  cv::erode(out.mask, shrunk, cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * ring_px + 1, 2 * ring_px + 1}));
  const double edge_contrast = mean_on(lum, out.mask & ~shrunk) / around;
  out.details["edge_contrast"] = edge_contrast;
  if (!(edge_contrast >= options.min_edge_contrast))
    return not_found("the patch's edge fades (contrast " + std::to_string(edge_contrast).substr(0, 4) +
                     "): lamp light, not sun");

  // Its outline on the floor.
  std::vector<cv::Point2f> points;
  for (int y = 0; y < out.mask.rows; ++y)
    for (int x = 0; x < out.mask.cols; ++x)
      if (out.mask.at<uint8_t>(y, x)) {
        const cv::Vec2f p = floor.xz.at<cv::Vec2f>(y, x);
        points.push_back({p[0], p[1]});
      }
  std::vector<cv::Point2f> hull;
  cv::convexHull(points, hull);
  out.area_m2 = hull.size() >= 3 ? cv::contourArea(hull) : 0.0;
  out.details["area_m2"] = out.area_m2;
  if (!(out.area_m2 >= options.min_area_m2)) return not_found("the patch covers too little floor");

  // Which wall, which way the sun: every outline that fits about as well,
  // each read both ways along its sun line.
  const Outline along[2] = {fit_outline(hull, 0, options), fit_outline(hull, 1, options)};
  const double best_area = std::min(along[0].area, along[1].area);
  Vector3d ahead = camera.R_world_from_cam.col(2);
  ahead.y() = 0;
  if (ahead.norm() > 1e-9) ahead.normalize();
  const double bright_level = options.min_brightness_ratio * reference;
  std::vector<SunHypothesis> hypotheses;
  for (const Outline& o : along) {
    if (!(o.area <= (1.0 + kSameFitShare) * best_area)) continue;
    const double length = o.b1 - o.b0;
    const double elevation = std::clamp(std::atan2(options.window_height_m, length), options.min_elevation_deg * kDegree,
                                        options.max_elevation_deg * kDegree);
    const Vector2d centre = 0.5 * (o.a0 + o.a1) * o.wall + 0.5 * (o.b0 + o.b1) * o.sun_line;
    for (const double sign : {1.0, -1.0}) {
      const Vector2d h = sign * o.sun_line;
      SunHypothesis s{o, Vector3d(std::cos(elevation) * h.x(), std::sin(elevation), std::cos(elevation) * h.y())};
      const Vector3d window_centre =
          floor_point(centre, floor_y) + s.direction * (options.window_centre_height_m / s.direction.y());
      s.seen = window_evidence(window_centre, depth, lum, bright_level, camera);
      s.behind = -Vector3d(h.x(), 0, h.y()).dot(ahead);
      hypotheses.push_back(s);
    }
  }
  // The window the photo would show and does first, then one it could not
  // show, the sun behind the camera before one beside it.
  const auto chosen = std::max_element(hypotheses.begin(), hypotheses.end(), [](const auto& a, const auto& b) {
    return std::tie(a.seen, a.behind) < std::tie(b.seen, b.behind);
  });
  if (chosen == hypotheses.end() || !chosen->direction.allFinite()) return not_found("no outline fits the patch");
  const SunHypothesis& sun = *chosen;
  const Outline& o = sun.outline;
  out.sun_direction = sun.direction.normalized();

  // The outline, a little wider for the penumbra, and the window above it
  // along the sun.
  const double ma = options.window_margin_share * (o.a1 - o.a0), mb = options.window_margin_share * (o.b1 - o.b0);
  const Vector2d corner = (o.a0 - ma) * o.wall + (o.b0 - mb) * o.sun_line;
  out.corner = floor_point(corner, floor_y);
  out.along_wall = floor_point((o.a1 - o.a0 + 2 * ma) * o.wall, 0.0);
  out.along_sun = floor_point((o.b1 - o.b0 + 2 * mb) * o.sun_line, 0.0);
  const double window_y = heights.ceiling_y && *heights.ceiling_y > floor_y + options.default_window_height_m / 2
                              ? *heights.ceiling_y - options.window_below_ceiling_m
                              : floor_y + options.default_window_height_m;
  out.window.corner = out.corner + out.sun_direction * ((window_y - floor_y) / out.sun_direction.y());
  out.window.edge_u = out.along_wall;
  out.window.edge_v = out.along_sun;
  if (!out.window.corner.allFinite()) return not_found("the window would not be finite");

  out.found = true;
  out.why = "a sharp-edged patch " + std::to_string(out.brightness_ratio).substr(0, 4) + "x the floor around it";
  out.details["wall_axis"] = o.wall_axis == 0 ? "x" : "z";
  out.details["shear_deg"] = o.shear_deg;
  out.details["length_along_sun_m"] = o.b1 - o.b0;
  out.details["width_along_wall_m"] = o.a1 - o.a0;
  out.details["elevation_deg"] = std::asin(std::clamp(out.sun_direction.y(), -1.0, 1.0)) / kDegree;
  out.details["sun_direction"] = {out.sun_direction.x(), out.sun_direction.y(), out.sun_direction.z()};
  out.details["window_seen"] = sun.seen;
  out.details["hypotheses"] = hypotheses.size();
  return out;
}

double take_sun_patch_out_of_albedo(cv::Mat& albedo, const SunPatch& patch) {
  if (!patch.found || albedo.type() != CV_32FC3 || patch.mask.size() != albedo.size() || patch.ring.size() != albedo.size())
    return 1.0;
  const cv::Mat lum = luminance_image(albedo);
  const double inside = mean_on(lum, patch.mask), around = mean_on(lum, patch.ring);
  if (!(around > kMinLuminance && inside > around)) return 1.0;
  const double factor = inside / around;
  cv::Mat scaled = albedo / factor;
  scaled.copyTo(albedo, patch.mask);
  return factor;
}

}  // namespace propcam::inference
