#include "propcam/inference/room_enclosure.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "depth_samples.h"
#include "propcam/render/mesh_shapes.h"

namespace propcam::inference {

using depth_samples::is_surface;
using depth_samples::percentile;
using Eigen::Vector3d;

void RoomEnclosure::validate() const {
  if (empty()) return;
  if (!min.allFinite() || !max.allFinite()) throw std::runtime_error("room enclosure: non-finite corner");
  if ((max - min).maxCoeff() > kMaxEnclosureExtentM)
    throw std::runtime_error("room enclosure: a side is longer than " + std::to_string(kMaxEnclosureExtentM) + " m");
  if (!albedo.allFinite() || albedo.minCoeff() < 0.f || albedo.maxCoeff() > 1.f)
    throw std::runtime_error("room enclosure: albedo outside [0, 1]");
}

RoomEnclosure enclose_room(const cv::Mat& depth, const cv::Mat& albedo, const render::PinholeCamera& camera,
                           const RoomHeights& heights, const std::vector<Vector3d>& light_positions,
                           const RoomEnclosureOptions& o) {
  if (depth.type() != CV_32F || depth.cols != camera.width || depth.rows != camera.height)
    throw std::invalid_argument("enclose_room: depth must be CV_32F at the camera's size");
  if (albedo.type() != CV_32FC3 || albedo.size() != depth.size())
    throw std::invalid_argument("enclose_room: albedo must be CV_32FC3 at the depth's size");
  const int step = std::max(1, depth.cols / std::max(1, o.sample_width));
  std::vector<double> xs, ys, zs;
  Eigen::Vector3d albedo_sum = Eigen::Vector3d::Zero();
  int albedo_count = 0;
  for (int y = step / 2; y < depth.rows; y += step)
    for (int x = step / 2; x < depth.cols; x += step) {
      const float d = depth.at<float>(y, x);
      if (!is_surface(d)) continue;
      const Vector3d p = depth_samples::world_point(camera, x, y, d);
      if (!p.allFinite()) continue;
      xs.push_back(p.x()), ys.push_back(p.y()), zs.push_back(p.z());
      const cv::Vec3f a = albedo.at<cv::Vec3f>(y, x);
      if (std::isfinite(a[0]) && std::isfinite(a[1]) && std::isfinite(a[2])) {
        albedo_sum += Vector3d(a[0], a[1], a[2]);
        ++albedo_count;
      }
    }
  RoomEnclosure box;
  if (xs.empty()) return box;
  const double lo = o.percentile, hi = 1.0 - o.percentile;
  box.min = Vector3d(percentile(xs, lo), percentile(ys, lo), percentile(zs, lo));
  box.max = Vector3d(percentile(xs, hi), percentile(ys, hi), percentile(zs, hi));
  // The camera stands inside, with room behind it and to its sides.
  const Vector3d c = camera.center_world;
  box.min = box.min.cwiseMin(Vector3d(c.x() - o.behind_camera_m, c.y(), c.z() - o.behind_camera_m));
  box.max = box.max.cwiseMax(Vector3d(c.x() + o.behind_camera_m, c.y(), c.z() + o.behind_camera_m));
  if (heights.floor_y && std::isfinite(*heights.floor_y)) box.min.y() = std::min(box.min.y(), *heights.floor_y);
  if (heights.ceiling_y && std::isfinite(*heights.ceiling_y)) box.max.y() = std::max(box.max.y(), *heights.ceiling_y);
  for (const Vector3d& l : light_positions)
    if (l.allFinite()) box.min = box.min.cwiseMin(l), box.max = box.max.cwiseMax(l);
  box.min.array() -= o.margin_m;
  box.max.array() += o.margin_m;
  // A few wild depths or a far light must not make a box no renderer can hold.
  const Vector3d half_limit = Vector3d::Constant(0.5 * kMaxEnclosureExtentM);
  box.min = box.min.cwiseMax(c - half_limit);
  box.max = box.max.cwiseMin(c + half_limit);
  if (albedo_count > 0) box.albedo = (albedo_sum / albedo_count).cwiseMax(0.0).cwiseMin(1.0).cast<float>();
  return box;
}

render::Mesh room_enclosure_mesh(const RoomEnclosure& box, const cv::Mat& depth, const render::PinholeCamera& camera,
                                 const RoomEnclosureOptions& o) {
  render::Mesh mesh;
  if (box.empty()) return mesh;
  box.validate();
  if (depth.type() != CV_32F || depth.cols != camera.width || depth.rows != camera.height)
    throw std::invalid_argument("room_enclosure_mesh: depth must be CV_32F at the camera's size");
  render::Material m;
  m.name = "room_enclosure";
  m.albedo = box.albedo;
  mesh.materials.push_back(m);
  // Seen through: in the frame and nearer than the surface the photo shows there.
  const auto seen_through = [&](const Vector3d& p) {
    Eigen::Vector2d px;
    if (!camera.project(p, px)) return false;
    const long x = std::lround(px.x()), y = std::lround(px.y());
    if (x < 0 || x >= camera.width || y < 0 || y >= camera.height) return false;
    const float d = depth.at<float>(static_cast<int>(y), static_cast<int>(x));
    const double seen = is_surface(d) ? d : std::numeric_limits<double>::infinity();
    return camera.world_to_camera(p).z() < (1.0 - o.free_space_margin) * seen;
  };
  const double cell = std::max(0.05, o.cell_m);
  // Each face: a fixed axis at one side of the box, spanned by two others,
  // its quad wound counter-clockwise seen from inside.
  for (int axis = 0; axis < 3; ++axis)
    for (const int side : {0, 1}) {
      const int a = (axis + 1) % 3, b = (axis + 2) % 3;
      const double fixed = side == 0 ? box.min[axis] : box.max[axis];
      const int na = std::clamp(static_cast<int>(std::ceil((box.max[a] - box.min[a]) / cell)), 1, kMaxEnclosureCellsPerSide);
      const int nb = std::clamp(static_cast<int>(std::ceil((box.max[b] - box.min[b]) / cell)), 1, kMaxEnclosureCellsPerSide);
      const double da = (box.max[a] - box.min[a]) / na, db = (box.max[b] - box.min[b]) / nb;
      const auto at = [&](double u, double v) {
        Vector3d p;
        p[axis] = fixed, p[a] = box.min[a] + u * da, p[b] = box.min[b] + v * db;
        return p;
      };
      for (int i = 0; i < na; ++i)
        for (int j = 0; j < nb; ++j) {
          if (seen_through(at(i + 0.5, j + 0.5))) continue;
          const Vector3d p00 = at(i, j), p10 = at(i + 1, j), p11 = at(i + 1, j + 1), p01 = at(i, j + 1);
          // (a x b) is the axis direction: seen from inside, the min face is
          // counter-clockwise as a, b; the max face as b, a.
          if (side == 0)
            render::add_quad(mesh, p00.cast<float>(), p10.cast<float>(), p11.cast<float>(), p01.cast<float>(), 0, 1.f);
          else
            render::add_quad(mesh, p00.cast<float>(), p01.cast<float>(), p11.cast<float>(), p10.cast<float>(), 0, 1.f);
        }
    }
  return mesh;
}

}  // namespace propcam::inference
