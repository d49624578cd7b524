#include "propcam/inference/support_planes.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "depth_samples.h"
#include "propcam/render/depth_mesh.h"

namespace propcam::inference {
namespace {

using Eigen::Vector3d;
using depth_samples::for_each_surface_sample;
using depth_samples::is_surface;
using depth_samples::percentile;
using depth_samples::world_point;

// Heights are histogrammed over this range around the floor (metres).
constexpr double kMinHeightM = -1.0;
constexpr double kMaxHeightM = 4.0;
// Extents use these percentiles of a plane's points, so a few stray pixels do
// not stretch a table across the room.
constexpr double kExtentLowPercentile = 0.03;
constexpr double kExtentHighPercentile = 0.97;
// Footprints smaller than this (metres) still flatten a few pixels.
constexpr double kMinFootprintM = 0.05;
// Without a support plane under it, the base's own normal must be this
// close to up (cos 30 degrees, render::kMaxSupportTiltDeg) to flatten anything.
constexpr float kMinBaseNormalUp = 0.866f;
// The flattened disc spans this many footprint radii.
constexpr double kFlattenRadiusFactor = 2.0;

void check_maps(const cv::Mat& depth, const cv::Mat& normals, const render::PinholeCamera& camera, const char* who) {
  if (depth.type() != CV_32F || normals.type() != CV_32FC3 || depth.size() != normals.size() ||
      depth.cols != camera.width || depth.rows != camera.height)
    throw std::invalid_argument(std::string(who) + ": depth (CV_32F) and normals (CV_32FC3) must be at the camera's size");
}

}  // namespace

std::vector<SupportPlane> find_support_planes(const cv::Mat& depth, const cv::Mat& normals,
                                              const render::PinholeCamera& camera, const SupportPlaneOptions& o,
                                              StageReport& report) {
  const auto start = std::chrono::steady_clock::now();
  check_maps(depth, normals, camera, "find_support_planes");
  if (!(o.bin_m > 0) || !(o.thickness_m > 0) || o.sample_width < 1 || o.max_planes < 1)
    throw std::invalid_argument("find_support_planes: bad options");
  const double cos_tilt = std::cos(o.max_tilt_deg * std::numbers::pi / 180.0);
  const int step = std::max(1, depth.cols / o.sample_width);
  struct Sample {
    Vector3d p;
  };
  std::vector<Sample> up;
  const int sampled = for_each_surface_sample(depth, step, [&](int x, int y, float d) {
    const cv::Vec3f n = normals.at<cv::Vec3f>(y, x);
    if (!(n[1] >= cos_tilt)) return;
    const Vector3d p = world_point(camera, x, y, d);
    if (!p.allFinite() || p.y() >= camera.center_world.y() || p.y() < kMinHeightM || p.y() > kMaxHeightM) return;
    up.push_back({p});
  });
  const double min_count = std::max(3.0, o.min_area_fraction * sampled);
  std::vector<double> heights;
  for (const auto& s : up) heights.push_back(s.p.y());
  std::vector<SupportPlane> planes;
  std::vector<bool> taken(up.size(), false);
  for (const double centre : depth_samples::histogram_peaks(heights, kMinHeightM, kMaxHeightM, o.bin_m, o.thickness_m,
                                                             min_count, o.max_planes, 3)) {
    std::vector<double> ys, xs, zs;
    for (size_t i = 0; i < up.size(); ++i)
      if (!taken[i] && std::abs(up[i].p.y() - centre) <= o.thickness_m) {
        taken[i] = true;
        ys.push_back(up[i].p.y());
        xs.push_back(up[i].p.x());
        zs.push_back(up[i].p.z());
      }
    if (ys.size() < min_count) continue;
    const double h = percentile(ys, 0.5);
    SupportPlane p;
    p.normal = Vector3d::UnitY();
    p.offset = -h;
    p.pixels = static_cast<int>(ys.size()) * step * step;
    p.extent_min = Vector3d(percentile(xs, kExtentLowPercentile), h, percentile(zs, kExtentLowPercentile));
    p.extent_max = Vector3d(percentile(xs, kExtentHighPercentile), h, percentile(zs, kExtentHighPercentile));
    planes.push_back(p);
  }
  // The lowest large surface near the floor is the floor; the rest are raised supports.
  std::sort(planes.begin(), planes.end(), [](const SupportPlane& a, const SupportPlane& b) { return a.offset > b.offset; });
  int raised = 0;
  bool have_floor = false;
  std::vector<SupportPlane> named;
  for (auto& p : planes) {
    const double h = -p.offset;
    if (!have_floor && h < o.min_table_height_m) {
      p.name = "floor";
      have_floor = true;
    } else if (h >= o.min_table_height_m) {
      p.name = "support_" + std::to_string(++raised);
    } else {
      continue;  // a second low layer (a rug's edge, a step): not a support of its own
    }
    named.push_back(p);
  }
  if (!have_floor) named.insert(named.begin(), SupportPlane{"floor", Vector3d::UnitY(), 0.0});
  report.stage = "support_planes";
  report.usable = true;
  report.why = std::to_string(raised) + " raised support surface(s)" + (have_floor ? ", floor seen" : ", floor not seen: y = 0");
  report.iterations = 1;
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  nlohmann::json list = nlohmann::json::array();
  for (const auto& p : named) list.push_back({{"name", p.name}, {"height_m", -p.offset}, {"pixels", p.pixels}});
  report.details = {{"planes", list}, {"upward_samples", up.size()}, {"samples", sampled}};
  return named;
}

InsertionFlattening flatten_insertion_region(cv::Mat& depth, cv::Mat& normals, const render::PinholeCamera& camera,
                                             const std::vector<SupportPlane>& planes, double u, double v,
                                             double footprint_radius_m, double max_offset_m) {
  check_maps(depth, normals, camera, "flatten_insertion_region");
  InsertionFlattening r;
  const int cx = static_cast<int>(std::lround(u)), cy = static_cast<int>(std::lround(v));
  if (!std::isfinite(u) || !std::isfinite(v) || cx < 0 || cy < 0 || cx >= depth.cols || cy >= depth.rows) {
    r.why = "the base pixel is outside the image";
    return r;
  }
  const float base_depth = depth.at<float>(cy, cx);
  if (!is_surface(base_depth)) {
    r.why = "the base pixel sees no surface";
    return r;
  }
  const double footprint = std::max(kMinFootprintM, std::isfinite(footprint_radius_m) ? footprint_radius_m : 0.0);
  const double radius_px =
      std::clamp(kFlattenRadiusFactor * footprint * camera.fx / base_depth, 2.0, 0.25 * std::max(depth.cols, depth.rows));
  const Vector3d base = world_point(camera, u, v, base_depth);
  // The plane: a support surface the base lies on, else the median height of
  // the upward-facing points around the base.
  double height = std::nan("");
  for (const auto& p : planes) {
    if (p.normal.y() < 0.99) continue;
    const double h = -p.offset / p.normal.y();
    if (std::abs(base.y() - h) <= max_offset_m && (std::isnan(height) || std::abs(base.y() - h) < std::abs(base.y() - height)))
      height = h;
  }
  const int x0 = std::max(0, static_cast<int>(u - radius_px)), x1 = std::min(depth.cols - 1, static_cast<int>(u + radius_px));
  const int y0 = std::max(0, static_cast<int>(v - radius_px)), y1 = std::min(depth.rows - 1, static_cast<int>(v + radius_px));
  if (std::isnan(height) && normals.at<cv::Vec3f>(cy, cx)[1] < kMinBaseNormalUp) {
    r.why = "the base is on no horizontal surface";
    return r;
  }
  if (std::isnan(height)) {
    std::vector<double> hs;
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        if ((x - u) * (x - u) + (y - v) * (y - v) > radius_px * radius_px) continue;
        const float d = depth.at<float>(y, x);
        if (!is_surface(d) || normals.at<cv::Vec3f>(y, x)[1] < 0.7f) continue;
        const Vector3d p = world_point(camera, x, y, d);
        if (std::abs(p.y() - base.y()) <= max_offset_m) hs.push_back(p.y());
      }
    height = hs.empty() ? base.y() : percentile(hs, 0.5);
    r.why = "plane fitted to " + std::to_string(hs.size()) + " points around the base";
  } else {
    r.why = "support plane at " + std::to_string(height) + " m";
  }
  if (height >= camera.center_world.y()) {
    r.why = "the base is above the camera: no horizontal support to flatten";
    return r;
  }
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) {
      if ((x - u) * (x - u) + (y - v) * (y - v) > radius_px * radius_px) continue;
      const float d = depth.at<float>(y, x);
      if (!is_surface(d)) continue;
      const Vector3d p = world_point(camera, x, y, d);
      if (std::abs(p.y() - height) > max_offset_m) continue;
      const Vector3d ray_cam((x - camera.cx) / camera.fx, (y - camera.cy) / camera.fy, 1.0);
      const double dy = (camera.R_world_from_cam * ray_cam).y();  // world y change per unit of depth
      if (dy > -1e-6) continue;                                    // the ray never reaches the plane
      const double new_depth = (height - camera.center_world.y()) / dy;
      if (!(new_depth > 0) || !std::isfinite(new_depth)) continue;
      depth.at<float>(y, x) = static_cast<float>(new_depth);
      normals.at<cv::Vec3f>(y, x) = cv::Vec3f(0.f, 1.f, 0.f);
      ++r.pixels_changed;
    }
  r.applied = r.pixels_changed > 0;
  r.plane_height_m = height;
  return r;
}

RoomHeights room_heights(const std::vector<SupportPlane>& planes) {
  RoomHeights h;
  for (const auto& p : planes) {
    if (!(std::abs(p.normal.y()) > 0.5)) continue;
    const double y = -p.offset / p.normal.y();
    if (p.name == "floor") h.floor_y = y;
    if (p.name == "ceiling") h.ceiling_y = y;
  }
  return h;
}

}  // namespace propcam::inference
