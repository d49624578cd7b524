#include "propcam/inference/contact_depth.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "propcam/inference/orientation_map.h"

namespace propcam::inference {
namespace {

using Eigen::Vector3d;

// Rays flatter than this (world y per unit length) never meet the floor in practice.
constexpr double kMinDownSlope = 0.02;
// Unknown pixels bridged inside a floor run (a grout line, a missed sweep).
constexpr int kMaxFloorGapPx = 2;
// Confidence of a vertical pixel whose orientation the map does not give
// (it borrows the box's) against one the map labels.
constexpr float kBorrowedOrientationConfidence = 0.5f;
constexpr float kLabelledConfidence = 1.0f;

uint8_t label_at(const cv::Mat& labels, int x, int y) { return labels.at<uint8_t>(y, x); }

}  // namespace

ContactDepth contact_depth_target(const cv::Mat& labels, const render::PinholeCamera& full_camera, const cv::Mat& box_normals) {
  if (labels.empty() || labels.type() != CV_8U) throw std::invalid_argument("contact_depth_target: labels must be CV_8U");
  if (!box_normals.empty() && (box_normals.type() != CV_32FC3 || box_normals.cols != full_camera.width ||
                               box_normals.rows != full_camera.height))
    throw std::invalid_argument("contact_depth_target: box normals must be CV_32FC3 at the camera's size");
  const int w = labels.cols, h = labels.rows;
  const render::PinholeCamera cam = full_camera.resized(w, h);
  const Vector3d c = cam.center_world;
  const Vector3d forward = cam.R_world_from_cam.col(2);
  ContactDepth out;
  out.depth = cv::Mat(h, w, CV_32F, cv::Scalar(0.f));
  out.confidence = cv::Mat(h, w, CV_32F, cv::Scalar(0.f));
  if (!(c.y() > 0)) return out;
  const auto floor_label = static_cast<uint8_t>(SurfaceOrientation::kNormalY);
  auto floor_t = [&](const Vector3d& d) { return d.y() < -kMinDownSlope ? c.y() / -d.y() : -1.0; };
  for (int x = 0; x < w; ++x) {
    // The floor run connected to the bottom of the column (small gaps bridged).
    int y = h - 1, gap = 0, top_floor = -1;
    for (; y >= 0; --y) {
      const bool floor = label_at(labels, x, y) == floor_label && floor_t(cam.ray_direction(x, y)) > 0;
      if (floor) {
        top_floor = y;
        gap = 0;
        const Vector3d d = cam.ray_direction(x, y);
        out.depth.at<float>(y, x) = static_cast<float>(floor_t(d) * d.dot(forward));
        out.confidence.at<float>(y, x) = kLabelledConfidence;
      } else if (top_floor >= 0 && label_at(labels, x, y) == 0 && ++gap <= kMaxFloorGapPx) {
        continue;
      } else if (top_floor >= 0 || label_at(labels, x, y) != 0) {
        break;
      }
    }
    if (top_floor <= 0) continue;
    // The contact: where the boundary ray (half a pixel above the top floor pixel) meets the floor.
    const Vector3d boundary = cam.ray_direction(x, top_floor - 0.5);
    const double t = floor_t(boundary);
    if (!(t > 0)) continue;
    const Vector3d contact = c + t * boundary;
    // The vertical surface above: its orientation from the map, else the box's.
    int first_label = 0;
    for (int yy = top_floor - 1; yy >= 0 && first_label == 0; --yy) {
      const uint8_t l = label_at(labels, x, yy);
      if (l == floor_label) break;
      first_label = l;
    }
    int axis = first_label == static_cast<int>(SurfaceOrientation::kNormalX)   ? 0
               : first_label == static_cast<int>(SurfaceOrientation::kNormalZ) ? 2
                                                                               : -1;
    float confidence = kLabelledConfidence;
    if (axis < 0) {
      if (box_normals.empty()) continue;
      const int fx = std::clamp(static_cast<int>((x + 0.5) * full_camera.width / w), 0, full_camera.width - 1);
      const int fy = std::clamp(static_cast<int>((top_floor - 0.5) * full_camera.height / h), 0, full_camera.height - 1);
      const cv::Vec3f n = box_normals.at<cv::Vec3f>(fy, fx);
      if (std::abs(n[1]) > 0.5f) continue;  // the box sees floor or ceiling there: no wall to borrow
      axis = std::abs(n[0]) > std::abs(n[2]) ? 0 : 2;
      confidence = kBorrowedOrientationConfidence;
    }
    ++out.columns_with_contact;
    for (int yy = top_floor - 1; yy >= 0; --yy) {
      const uint8_t l = label_at(labels, x, yy);
      const bool same = l == 0 || l == (axis == 0 ? static_cast<uint8_t>(SurfaceOrientation::kNormalX)
                                                  : static_cast<uint8_t>(SurfaceOrientation::kNormalZ));
      if (!same) break;  // another surface: its contact is not this one
      const Vector3d d = cam.ray_direction(x, yy);
      const double along = d(axis);
      if (std::abs(along) < 1e-6) break;
      const double tt = (contact(axis) - c(axis)) / along;
      if (!(tt > 0) || !std::isfinite(tt)) break;
      out.depth.at<float>(yy, x) = static_cast<float>(tt * d.dot(forward));
      out.confidence.at<float>(yy, x) = l == 0 ? kBorrowedOrientationConfidence * confidence : confidence;
    }
  }
  return out;
}

std::vector<Vector3d> seen_floor_points(const cv::Mat& labels, const render::PinholeCamera& full_camera) {
  if (labels.empty() || labels.type() != CV_8U) throw std::invalid_argument("seen_floor_points: labels must be CV_8U");
  const render::PinholeCamera cam = full_camera.resized(labels.cols, labels.rows);
  std::vector<Vector3d> points;
  if (!(cam.center_world.y() > 0)) return points;
  for (int y = 0; y < labels.rows; ++y)
    for (int x = 0; x < labels.cols; ++x) {
      if (labels.at<uint8_t>(y, x) != static_cast<uint8_t>(SurfaceOrientation::kNormalY)) continue;
      const Vector3d d = cam.ray_direction(x, y);
      if (d.y() < -kMinDownSlope) points.push_back(cam.center_world + d * (cam.center_world.y() / -d.y()));
    }
  return points;
}

}  // namespace propcam::inference
