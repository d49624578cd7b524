#include "propcam/inference/lit_wall_lamp.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "depth_samples.h"
#include "luminance.h"
#include "propcam/inference/support_planes.h"

namespace propcam::inference {
namespace {

using Eigen::Vector3d;

// Below this luminance a pixel (or its albedo) is black: no ratio means anything.
constexpr double kMinLuminance = 1e-4;
// The photo would show the lamp where it sees this much past it.
constexpr double kSeenPastShare = 1.1;
// A lamp nearer the camera's plane than this (m) is behind it.
constexpr double kMinViewDepthM = 0.1;
// The floor is at y = 0; the lamp is searched between these heights
// (above the floor and below the ceiling).
constexpr double kMinLampHeightM = 0.2, kBelowCeilingM = 0.1;
// The ceiling when the layout has none.
constexpr double kDefaultCeilingM = 2.7;
// The shading's variance must exceed this share of its mean square for a
// falloff to be read at all.
constexpr double kMinRelativeVariance = 1e-4;

struct Sample {
  Vector3d point, normal;
  double shading = 0.0;
};

std::string percent(double share) { return std::to_string(static_cast<int>(std::lround(100 * share))) + "%"; }

bool is_room_surface(const SupportPlane& p) { return p.name == "ceiling" || p.name.rfind("wall", 0) == 0; }

std::vector<Sample> sample_surfaces(const cv::Mat& photo, const cv::Mat& depth, const cv::Mat& albedo,
                                    const render::PinholeCamera& camera, const std::vector<SupportPlane>& surfaces,
                                    const cv::Mat& sources, const LitWallLampOptions& options) {
  const int step = std::max(1, photo.cols / std::max(1, options.sample_width));
  std::vector<Sample> out;
  depth_samples::for_each_surface_sample(depth, step, [&](int x, int y, float d) {
    if (!sources.empty() && sources.at<uint8_t>(y, x)) return;
    const cv::Vec3f rgb = photo.at<cv::Vec3f>(y, x);
    if (!std::isfinite(rgb[0] + rgb[1] + rgb[2]) || std::max({rgb[0], rgb[1], rgb[2]}) >= options.clipped_level) return;
    const double lum = luminance(rgb);
    double reflectance = 1.0;
    if (!albedo.empty()) {
      reflectance = luminance(albedo.at<cv::Vec3f>(y, x));
      if (!std::isfinite(reflectance) || reflectance < kMinLuminance) return;
    }
    if (!std::isfinite(lum) || lum < kMinLuminance) return;
    const Vector3d point = depth_samples::world_point(camera, x, y, d);
    const SupportPlane* nearest = nullptr;
    double nearest_distance = options.max_plane_distance_m;
    for (const auto& plane : surfaces) {
      const double distance = std::abs(plane.normal.dot(point) + plane.offset);
      if (distance <= nearest_distance) nearest = &plane, nearest_distance = distance;
    }
    if (nearest) out.push_back({point, nearest->normal, lum / reflectance});
  });
  return out;
}

// The least-squares fit of shading = ambient + power * falloff, both >= 0,
// and its residuals' sum of squares without the worst `trim` of them.
struct FalloffFit {
  double ambient = 0.0, power = 0.0, trimmed_sse = std::numeric_limits<double>::infinity();
};

double trimmed_sum_of_squares(std::vector<double>& squared, double trim) {
  const size_t keep = std::max<size_t>(1, static_cast<size_t>((1.0 - trim) * squared.size()));
  if (keep < squared.size()) std::nth_element(squared.begin(), squared.begin() + keep, squared.end());
  double sum = 0.0;
  for (size_t i = 0; i < keep; ++i) sum += squared[i];
  return sum;
}

FalloffFit fit_falloff(const std::vector<Sample>& samples, const std::vector<double>& falloff, double trim,
                       std::vector<double>& scratch) {
  const double n = static_cast<double>(samples.size());
  double sb = 0, sbb = 0, ss = 0, sbs = 0;
  for (size_t i = 0; i < samples.size(); ++i) {
    sb += falloff[i], sbb += falloff[i] * falloff[i], ss += samples[i].shading, sbs += falloff[i] * samples[i].shading;
  }
  FalloffFit fit;
  const double det = n * sbb - sb * sb;
  if (det > 1e-12 * n * sbb) {
    fit.power = (n * sbs - sb * ss) / det;
    fit.ambient = (ss - fit.power * sb) / n;
  }
  if (fit.power <= 0.0) fit.power = 0.0, fit.ambient = ss / n;
  else if (fit.ambient < 0.0) fit.ambient = 0.0, fit.power = sbb > 0 ? sbs / sbb : 0.0;
  scratch.resize(samples.size());
  for (size_t i = 0; i < samples.size(); ++i) {
    const double r = samples[i].shading - fit.ambient - fit.power * falloff[i];
    scratch[i] = r * r;
  }
  fit.trimmed_sse = trimmed_sum_of_squares(scratch, trim);
  return fit;
}

// Whether the photo would show a lamp at `p`: it is in the frame, in front
// of the camera, and the photo sees past it there.
bool photo_would_show(const Vector3d& p, const cv::Mat& depth, const render::PinholeCamera& camera) {
  const auto at = depth_samples::seen_at(camera, depth, p, kMinViewDepthM);
  return at && (!depth_samples::is_surface(at->seen_depth) || at->seen_depth > kSeenPastShare * at->point_depth);
}

struct RoomBox {
  Vector3d lo, hi;
};

RoomBox room_box(const render::PinholeCamera& camera, const std::vector<SupportPlane>& planes,
                 const LitWallLampOptions& options) {
  const std::optional<double> fitted = room_heights(planes).ceiling_y;
  const double ceiling =
      fitted && std::isfinite(*fitted) && *fitted > kMinLampHeightM + kBelowCeilingM ? *fitted : kDefaultCeilingM;
  const double half = options.default_half_extent_m;
  return {Vector3d(camera.center_world.x() - half, kMinLampHeightM, camera.center_world.z() - half),
          Vector3d(camera.center_world.x() + half, ceiling - kBelowCeilingM, camera.center_world.z() + half)};
}

// How a lamp at `p` would light each sample (cos / d^2), or false where it
// cannot stand: outside a wall, too near a surface or the camera, or where
// the photo would show it.
bool falloff_at(const Vector3d& p, const std::vector<Sample>& samples, const std::vector<SupportPlane>& walls,
                const cv::Mat& depth, const render::PinholeCamera& camera, const LitWallLampOptions& options,
                std::vector<double>& falloff) {
  for (const auto& w : walls)
    if (w.normal.dot(p) + w.offset < options.min_clearance_m) return false;
  if ((p - camera.center_world).norm() < options.min_clearance_m) return false;
  if (photo_would_show(p, depth, camera)) return false;
  falloff.resize(samples.size());
  for (size_t i = 0; i < samples.size(); ++i) {
    const Vector3d to_lamp = p - samples[i].point;
    const double d = to_lamp.norm();
    if (d < options.min_clearance_m) return false;
    falloff[i] = std::max(0.0, samples[i].normal.dot(to_lamp)) / (d * d * d);
  }
  return true;
}

}  // namespace

LitWallLamp find_lit_wall_lamp(const cv::Mat& photo_linear, const cv::Mat& depth, const cv::Mat& albedo,
                               const render::PinholeCamera& camera, const std::vector<SupportPlane>& planes,
                               const cv::Mat& sources, const LitWallLampOptions& options) {
  LitWallLamp out;
  if (photo_linear.empty() || photo_linear.type() != CV_32FC3 || depth.type() != CV_32F ||
      depth.size() != photo_linear.size() || (!albedo.empty() && (albedo.type() != CV_32FC3 || albedo.size() != photo_linear.size())) ||
      (!sources.empty() && (sources.type() != CV_8U || sources.size() != photo_linear.size()))) {
    out.why = "photo, depth, albedo and sources must share one size (CV_32FC3, CV_32F, CV_32FC3, CV_8U)";
    return out;
  }
  if (!camera.center_world.allFinite() || !camera.R_world_from_cam.allFinite() || !(camera.fx > 0) || !(camera.fy > 0)) {
    out.why = "no usable camera";
    return out;
  }
  std::vector<SupportPlane> surfaces, walls;
  for (const auto& p : planes) {
    if (!is_room_surface(p) || !p.normal.allFinite() || !std::isfinite(p.offset)) continue;
    surfaces.push_back(p);
    if (p.name != "ceiling") walls.push_back(p);
  }
  if (surfaces.empty()) {
    out.why = "the layout has no walls or ceiling";
    return out;
  }
  const std::vector<Sample> samples = sample_surfaces(photo_linear, depth, albedo, camera, surfaces, sources, options);
  out.samples = static_cast<int>(samples.size());
  out.details["samples"] = out.samples;
  if (out.samples < options.min_samples) {
    out.why = "too little wall seen (" + std::to_string(out.samples) + " samples)";
    return out;
  }
  // The constant the walls would have with no lamp: the reference every
  // position is scored against.
  std::vector<double> scratch, falloff(samples.size(), 0.0);
  const FalloffFit flat = fit_falloff(samples, falloff, options.trim_share, scratch);
  double mean_square = 0.0;
  for (const auto& s : samples) mean_square += s.shading * s.shading;
  mean_square /= samples.size();
  if (!(flat.trimmed_sse > kMinRelativeVariance * mean_square * samples.size())) {
    out.why = "the walls are evenly lit";
    return out;
  }
  const RoomBox box = room_box(camera, planes, options);
  Vector3d best_position = Vector3d::Zero();
  FalloffFit best;
  int positions = 0;
  const auto try_position = [&](const Vector3d& p) {
    if (!falloff_at(p, samples, walls, depth, camera, options, falloff)) return;
    ++positions;
    const FalloffFit fit = fit_falloff(samples, falloff, options.trim_share, scratch);
    if (fit.trimmed_sse < best.trimmed_sse) best = fit, best_position = p;
  };
  const Eigen::Vector3i steps(std::max(2, options.grid_xz), std::max(2, options.grid_y), std::max(2, options.grid_xz));
  const Vector3d cell = (box.hi - box.lo).cwiseQuotient((steps - Eigen::Vector3i::Ones()).cast<double>());
  for (int i = 0; i < steps.x(); ++i)
    for (int j = 0; j < steps.y(); ++j)
      for (int k = 0; k < steps.z(); ++k) try_position(box.lo + cell.cwiseProduct(Vector3d(i, j, k)));
  if (!std::isfinite(best.trimmed_sse)) {
    out.why = "no place in the room where a lamp would stay unseen";
    return out;
  }
  // Refine around the best position: a pattern search whose step halves
  // each round, from one grid cell.
  Vector3d step = cell;
  for (int round = 0; round < options.refine_rounds; ++round) {
    step /= 2.0;
    const Vector3d centre = best_position;
    for (int i = -1; i <= 1; ++i)
      for (int j = -1; j <= 1; ++j)
        for (int k = -1; k <= 1; ++k) {
          const Vector3d p = centre + step.cwiseProduct(Vector3d(i, j, k));
          if (p.y() >= box.lo.y() && p.y() <= box.hi.y() && (i || j || k)) try_position(p);
        }
  }
  out.position = best_position;
  out.explained = 1.0 - best.trimmed_sse / flat.trimmed_sse;
  falloff_at(best_position, samples, walls, depth, camera, options, falloff);
  for (size_t i = 0; i < samples.size(); ++i) {
    const double lamp = best.power * falloff[i];
    if (lamp + best.ambient > 0) out.lamp_share = std::max(out.lamp_share, lamp / (lamp + best.ambient));
  }
  out.details["positions"] = positions;
  out.details["position"] = {out.position.x(), out.position.y(), out.position.z()};
  out.details["explained"] = out.explained;
  out.details["lamp_share"] = out.lamp_share;
  if (out.explained < options.min_explained) {
    out.why = "no lamp's falloff explains the walls' shading (" + percent(out.explained) + " of its variance)";
    return out;
  }
  if (out.lamp_share < options.min_lamp_share) {
    out.why = "the falloff is too faint beside the room's other light";
    return out;
  }
  out.found = true;
  out.why = "a lamp's falloff explains " + percent(out.explained) + " of the walls' shading";
  return out;
}

}  // namespace propcam::inference
