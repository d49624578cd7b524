#include "propcam/inference/layout.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <opencv2/imgproc.hpp>

#include "propcam/render/depth_mesh.h"

namespace propcam::inference {
namespace {

using Eigen::Vector3d;

// Rays flatter than this never reach the floor or ceiling in practice.
constexpr double kMinVerticalComponent = 1e-4;
// A floor contact must be at least this far below the horizon (ray y).
constexpr double kMinFloorRaySlope = 0.02;

// Contacts on one wall share its distance; contacts of the neighbouring
// walls and of furniture spread nearer, and edges that stop above the floor
// (panelling, frames) farther. The densest distance (a kernel density in
// log-distance, so far contacts may scatter more) is the wall. The median of
// all contacts had dragged walls towards the camera (generator rooms 1-8:
// depth abs-rel 0.21 -> 0.09); the farthest dense cluster is worse (0.48):
// panelling that stops at a dado rail makes a dense cluster beyond the wall.
constexpr double kContactBandwidthLog = 0.05;
// Share of the seen floor a wall must stand behind (the rest may be mislabelled).
constexpr double kSeenFloorPercentile = 0.95;
constexpr int kMinContactsForMode = 3;

double wall_distance_from_contacts(const std::vector<double>& d) {
  double best = d.front(), best_density = -1;
  for (double candidate : d) {
    double density = 0;
    for (double other : d) {
      const double z = (std::log(other) - std::log(candidate)) / kContactBandwidthLog;
      density += std::exp(-0.5 * z * z);
    }
    if (density > best_density) {
      best_density = density;
      best = candidate;
    }
  }
  return best;
}

// A vertical segment j continues segment i downwards when i's lower end lies
// on j's line (within kContinuationOffsetPx) and j starts just below it
// (within kContinuationGapFraction of the image height).
constexpr double kContinuationOffsetPx = 3.0;
constexpr double kContinuationGapFraction = 0.08;

bool continues_downwards(const std::vector<LineSegment>& lines, const std::vector<int>& labels, size_t i, int height) {
  const LineSegment& li = lines[i];
  const Eigen::Vector2d low = li.a.y() > li.b.y() ? li.a : li.b;  // image y grows downwards
  for (size_t j = 0; j < lines.size() && j < labels.size(); ++j) {
    if (j == i || labels[j] != 1) continue;
    const LineSegment& lj = lines[j];
    const Eigen::Vector2d top = lj.a.y() < lj.b.y() ? lj.a : lj.b;
    const Eigen::Vector2d dir = (lj.b - lj.a);
    const double len = dir.norm();
    if (len < 1e-9) continue;
    const double offset = std::abs(dir.x() * (low.y() - lj.a.y()) - dir.y() * (low.x() - lj.a.x())) / len;
    const double gap = top.y() - low.y();
    if (offset <= kContinuationOffsetPx && gap > -kContinuationOffsetPx && gap <= kContinuationGapFraction * height)
      return true;
  }
  return false;
}

// Which wall orientation the orientation map shows on both sides of a
// vertical edge's lower half: 0 (normal along X), 2 (along Z) or -1 (unknown
// or mixed). A clear majority of kMinBesideShare of the samples decides.
constexpr double kMinBesideShare = 0.6;
constexpr double kBesideOffsetPx = 4.0;

int wall_axis_beside(const LineSegment& line, const cv::Mat& orientation, const render::PinholeCamera& camera) {
  if (orientation.empty()) return -1;
  const Eigen::Vector2d low = line.a.y() > line.b.y() ? line.a : line.b, high = line.a.y() > line.b.y() ? line.b : line.a;
  const double sx = static_cast<double>(orientation.cols) / camera.width, sy = static_cast<double>(orientation.rows) / camera.height;
  int votes[4] = {0, 0, 0, 0}, total = 0;
  for (int k = 0; k <= 8; ++k) {
    const Eigen::Vector2d q = low + (high - low) * (0.5 * k / 8.0);
    for (double side : {-kBesideOffsetPx, kBesideOffsetPx}) {
      const int x = static_cast<int>((q.x() + side) * sx), y = static_cast<int>(q.y() * sy);
      if (x < 0 || y < 0 || x >= orientation.cols || y >= orientation.rows) continue;
      ++total;
      ++votes[std::min<int>(orientation.at<uint8_t>(y, x), 3)];
    }
  }
  if (total == 0) return -1;
  if (votes[1] >= kMinBesideShare * total) return 0;  // kNormalX
  if (votes[3] >= kMinBesideShare * total) return 2;  // kNormalZ
  return -1;
}

}  // namespace

Layout estimate_layout(const render::PinholeCamera& camera, const std::vector<LineSegment>& lines,
                       const std::vector<int>& line_labels, bool indoor, const LayoutOptions& options,
                       const cv::Mat& sky_mask, const std::vector<Vector3d>& seen_floor, const cv::Mat& orientation) {
  const auto start = std::chrono::steady_clock::now();
  if (!sky_mask.empty() && (sky_mask.type() != CV_8U || sky_mask.cols != camera.width || sky_mask.rows != camera.height))
    throw std::invalid_argument("estimate_layout: the sky mask must be CV_8U at the camera's size");
  Layout layout;
  const double h = camera.center_world.y();
  // Floor contacts: the lower end of each vertical edge seen below the
  // horizon, unless another vertical edge continues it downwards (panelling
  // below a rail: that end is on the wall, not on the floor).
  std::vector<Vector3d> contacts;
  std::vector<int> contact_axis;  // 0: on a wall facing along X, 2: along Z, -1: unknown
  for (size_t i = 0; i < lines.size() && i < line_labels.size(); ++i) {
    if (line_labels[i] != 1 || continues_downwards(lines, line_labels, i, camera.height)) continue;
    const Vector3d da = camera.ray_direction(lines[i].a.x(), lines[i].a.y());
    const Vector3d db = camera.ray_direction(lines[i].b.x(), lines[i].b.y());
    const Vector3d& low = da.y() < db.y() ? da : db;
    if (low.y() > -kMinFloorRaySlope) continue;
    const Vector3d p = camera.center_world + low * (h / -low.y());
    if (!p.allFinite()) continue;
    contacts.push_back(p);
    contact_axis.push_back(wall_axis_beside(lines[i], orientation, camera));
  }
  // Wall distance in each horizontal direction (+X, -X, +Z, -Z) from the camera.
  const double fallback = indoor ? options.default_wall_distance_indoor_m : options.default_wall_distance_outdoor_m;
  const Vector3d axes[4] = {Vector3d::UnitX(), -Vector3d::UnitX(), Vector3d::UnitZ(), -Vector3d::UnitZ()};
  const char* names[4] = {"wall_pos_x", "wall_neg_x", "wall_pos_z", "wall_neg_z"};
  double wall[4];
  int evidence[4];
  bool pushed_by_floor[4] = {false, false, false, false};
  for (int a = 0; a < 4; ++a) {
    std::vector<double> dist;
    for (size_t c = 0; c < contacts.size(); ++c) {
      const Vector3d& p = contacts[c];
      const double d = (p - camera.center_world).dot(axes[a]);
      const int axis = a < 2 ? 0 : 2;
      // The orientation map says which wall the edge stands on; where it is
      // silent, count the contact for the wall it is most in front of.
      if (contact_axis[c] >= 0) {
        if (contact_axis[c] == axis && d > 0) dist.push_back(d);
        continue;
      }
      const Vector3d rel = p - camera.center_world;
      const double lateral = std::abs(a < 2 ? rel.z() : rel.x());
      if (d > 0 && d >= lateral * 0.5) dist.push_back(d);
    }
    evidence[a] = static_cast<int>(dist.size());
    wall[a] = dist.size() >= kMinContactsForMode ? wall_distance_from_contacts(dist)
              : dist.empty()                        ? fallback
                                                    : *std::max_element(dist.begin(), dist.end());
    // Floor seen beyond a wall would be outside the room: every wall stands
    // at least as far as (a high percentile of) the floor seen towards it.
    if (!seen_floor.empty()) {
      std::vector<double> beyond;
      for (const Vector3d& p : seen_floor) beyond.push_back((p - camera.center_world).dot(axes[a]));
      const size_t k = static_cast<size_t>(kSeenFloorPercentile * (beyond.size() - 1));
      std::nth_element(beyond.begin(), beyond.begin() + k, beyond.end());
      if (beyond[k] > wall[a]) {
        wall[a] = beyond[k];
        pushed_by_floor[a] = true;
      }
    }
    wall[a] = std::clamp(wall[a] + 0.05, options.min_wall_distance_m, options.max_depth_m);
  }

  layout.depth = cv::Mat(camera.height, camera.width, CV_32F);
  layout.normals = cv::Mat(camera.height, camera.width, CV_32FC3);
  const double ceiling = std::max(options.ceiling_height_m, h + 0.3);
  const Vector3d forward = camera.R_world_from_cam.col(2);
  for (int y = 0; y < camera.height; ++y)
    for (int x = 0; x < camera.width; ++x) {
      const Vector3d d = camera.ray_direction(x, y);
      double t = options.max_depth_m / std::max(d.dot(forward), 1e-3);
      Vector3d n = -d;
      auto consider = [&](double candidate, const Vector3d& normal) {
        if (candidate > 0 && candidate < t) {
          t = candidate;
          n = normal;
        }
      };
      if (d.y() < -kMinVerticalComponent) consider(h / -d.y(), Vector3d::UnitY());
      if (indoor && d.y() > kMinVerticalComponent) consider((ceiling - h) / d.y(), -Vector3d::UnitY());
      for (int a = 0; a < 4; ++a) {
        const double along = d.dot(axes[a]);
        if (along > kMinVerticalComponent) consider(wall[a] / along, -axes[a]);
      }
      const double z = std::min(t * d.dot(forward), options.max_depth_m);
      const bool sky = !sky_mask.empty() && sky_mask.at<uint8_t>(y, x) != 0;
      layout.depth.at<float>(y, x) = sky ? render::kSkyDepthM : static_cast<float>(std::max(z, 1e-3));
      if (sky) n = -d;
      layout.normals.at<cv::Vec3f>(y, x) = cv::Vec3f(static_cast<float>(n.x()), static_cast<float>(n.y()),
                                                     static_cast<float>(n.z()));
    }
  layout.planes.push_back({"floor", Vector3d::UnitY(), 0.0});
  if (indoor) layout.planes.push_back({"ceiling", -Vector3d::UnitY(), ceiling});
  for (int a = 0; a < 4; ++a) layout.planes.push_back({names[a], -axes[a], wall[a]});

  StageReport& r = layout.report;
  r.stage = "geometry";
  r.usable = true;
  r.why = contacts.empty() ? "no floor contacts: default room box" : "box fitted to floor contacts";
  r.iterations = 1;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.details = {{"floor_contacts", contacts.size()},
               {"walls_m", {wall[0], wall[1], wall[2], wall[3]}},
               {"walls_evidence", {evidence[0], evidence[1], evidence[2], evidence[3]}},
               {"walls_pushed_by_seen_floor", {pushed_by_floor[0], pushed_by_floor[1], pushed_by_floor[2], pushed_by_floor[3]}},
               {"seen_floor_points", seen_floor.size()},
               {"indoor", indoor}};
  return layout;
}

}  // namespace propcam::inference
