#include "propcam/inference/hidden_facades.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include <opencv2/imgproc.hpp>

#include "depth_samples.h"
#include "propcam/render/depth_mesh.h"
#include "propcam/render/mesh_shapes.h"

namespace propcam::inference {
namespace {

using Eigen::Vector3d;

// The four horizontal world axes a Manhattan facade can face.
const std::array<Vector3d, 4> kAxes = {Vector3d::UnitX(), -Vector3d::UnitX(), Vector3d::UnitZ(), -Vector3d::UnitZ()};
// Plane offsets are histogrammed over this range (metres from the origin);
// surfaces farther away are not facades to continue.
constexpr double kMaxOffsetM = 200.0;
// A facade lower than this is a kerb, a car or a wall-like fence: not continued.
constexpr double kMinFacadeHeightM = 2.0;
// Cells no smaller than this, and no more of them in one mesh than this
// (a facade from a scene file is bounded by kMaxFacadeSpanM; this bounds
// the memory a mesh may take whatever the options).
constexpr double kMinCellM = 0.05;
constexpr size_t kMaxHiddenCells = 100000;

struct VerticalSample {
  Vector3d point;
  int axis = 0;
  int column = 0;
  cv::Vec3f albedo;
};

}  // namespace

std::vector<HiddenFacade> find_hidden_facades(const cv::Mat& depth, const cv::Mat& normals, const cv::Mat& albedo,
                                              const render::PinholeCamera& camera, const HiddenFacadeOptions& o) {
  if (depth.type() != CV_32F || normals.type() != CV_32FC3 || depth.size() != normals.size() ||
      depth.cols != camera.width || depth.rows != camera.height)
    throw std::invalid_argument("find_hidden_facades: depth (CV_32F) and normals (CV_32FC3) must be at the camera's size");
  if (!albedo.empty() && albedo.type() != CV_32FC3)
    throw std::invalid_argument("find_hidden_facades: albedo must be CV_32FC3");
  if (!(o.bin_m > 0) || !(o.thickness_m > 0) || o.sample_width < 1 || o.max_facades < 0)
    throw std::invalid_argument("find_hidden_facades: bad options");
  cv::Mat albedo_here;
  if (!albedo.empty()) cv::resize(albedo, albedo_here, depth.size(), 0, 0, cv::INTER_AREA);
  const double min_axis_cos = std::cos(o.max_axis_deviation_deg * std::numbers::pi / 180.0);
  const int step = std::max(1, depth.cols / o.sample_width);
  std::vector<VerticalSample> samples;
  const int sampled = depth_samples::for_each_surface_sample(depth, step, [&](int x, int y, float d) {
    const cv::Vec3f nv = normals.at<cv::Vec3f>(y, x);
    const Vector3d n(nv[0], nv[1], nv[2]);
    if (!n.allFinite() || !(std::abs(n.y()) < o.max_normal_up)) return;
    const Vector3d horizontal = Vector3d(n.x(), 0, n.z()).normalized();
    int axis = -1;
    for (int a = 0; a < 4; ++a)
      if (horizontal.dot(kAxes[a]) >= min_axis_cos) axis = a;
    if (axis < 0) return;
    const Vector3d p = depth_samples::world_point(camera, x, y, d);
    if (!p.allFinite() || std::abs(kAxes[axis].dot(p)) >= kMaxOffsetM) return;
    samples.push_back({p, axis, x / step, albedo_here.empty() ? cv::Vec3f(0.5f, 0.5f, 0.5f) : albedo_here.at<cv::Vec3f>(y, x)});
  });
  std::vector<HiddenFacade> out;
  if (sampled == 0 || o.max_facades == 0) return out;
  const double min_count = std::max(8.0, o.min_area_fraction * sampled);
  struct Candidate {
    int axis;
    double offset;
    std::vector<size_t> members;
  };
  std::vector<Candidate> candidates;
  for (int axis = 0; axis < 4; ++axis) {
    // Offsets of the plane normal . x + offset = 0 through each point.
    std::vector<double> offsets;
    for (const auto& s : samples)
      if (s.axis == axis) offsets.push_back(-kAxes[axis].dot(s.point));
    for (const double offset : depth_samples::histogram_peaks(offsets, -kMaxOffsetM, kMaxOffsetM, o.bin_m, o.thickness_m,
                                                               min_count, o.max_facades, 2)) {
      Candidate c{axis, offset, {}};
      for (size_t i = 0; i < samples.size(); ++i)
        if (samples[i].axis == axis && std::abs(-kAxes[axis].dot(samples[i].point) - c.offset) <= o.thickness_m)
          c.members.push_back(i);
      if (c.members.size() >= min_count) candidates.push_back(std::move(c));
    }
  }
  std::sort(candidates.begin(), candidates.end(),
            [](const Candidate& a, const Candidate& b) { return a.members.size() > b.members.size(); });
  for (const Candidate& c : candidates) {
    if (static_cast<int>(out.size()) >= o.max_facades) break;
    HiddenFacade f;
    f.normal = kAxes[c.axis];
    f.offset = c.offset;
    // The camera must be on the side the facade faces (it was seen from there).
    if (!(f.normal.dot(camera.center_world) + f.offset > 0)) continue;
    const Vector3d along = Vector3d::UnitY().cross(f.normal);
    std::vector<double> heights, positions;
    std::vector<double> column_top(static_cast<size_t>(depth.cols / step + 1), -std::numeric_limits<double>::infinity());
    Eigen::Vector3d albedo_sum = Eigen::Vector3d::Zero();
    for (size_t i : c.members) {
      const VerticalSample& s = samples[i];
      heights.push_back(s.point.y());
      positions.push_back(along.dot(s.point));
      column_top[s.column] = std::max(column_top[s.column], s.point.y());
      albedo_sum += Eigen::Vector3d(s.albedo[0], s.albedo[1], s.albedo[2]);
    }
    std::vector<double> tops;
    for (double t : column_top)
      if (std::isfinite(t)) tops.push_back(t);
    f.bottom_m = std::min(0.0, depth_samples::percentile(heights, 0.03));
    f.top_m = depth_samples::percentile(tops, 0.5);
    if (!(f.top_m - f.bottom_m >= kMinFacadeHeightM)) continue;
    const double camera_along = along.dot(camera.center_world);
    f.seen_min = depth_samples::percentile(positions, 0.03);
    f.seen_max = depth_samples::percentile(positions, 0.97);
    f.along_min = std::min(f.seen_min, camera_along - o.reach_m);
    f.along_max = std::max(f.seen_max, camera_along + o.reach_m);
    f.albedo = (albedo_sum / static_cast<double>(c.members.size())).cwiseMax(0.0).cwiseMin(1.0).cast<float>();
    f.pixels = static_cast<int>(c.members.size());
    out.push_back(f);
  }
  return out;
}

render::Mesh hidden_facade_mesh(const std::vector<HiddenFacade>& facades, const cv::Mat& depth,
                                const render::PinholeCamera& camera, const HiddenFacadeOptions& o) {
  render::Mesh mesh;
  if (!(o.cell_m >= kMinCellM)) throw std::invalid_argument("hidden_facade_mesh: cell size must be at least 5 cm");
  if (depth.type() != CV_32F || depth.cols != camera.width || depth.rows != camera.height)
    throw std::invalid_argument("hidden_facade_mesh: depth must be CV_32F at the camera's size");
  // Seen in the frame (in front of the camera)?
  const auto in_view = [&](const Vector3d& p, Eigen::Vector2d& px) {
    return camera.project(p, px) && px.x() >= 0 && px.x() <= camera.width && px.y() >= 0 && px.y() <= camera.height;
  };
  // Seen through: in the frame and nearer than the surface the photo shows there.
  const auto in_free_space = [&](const Vector3d& p) {
    Eigen::Vector2d px;
    if (!in_view(p, px)) return false;
    const int x = std::clamp(static_cast<int>(px.x()), 0, depth.cols - 1), y = std::clamp(static_cast<int>(px.y()), 0, depth.rows - 1);
    const float d = depth.at<float>(y, x);
    const double seen = std::isfinite(d) && d > 0 ? d : std::numeric_limits<double>::infinity();  // sky: seen through
    return camera.world_to_camera(p).z() < (1.0 - o.free_space_margin) * seen;
  };
  const auto full = [&] { return mesh.triangles.size() >= 2 * kMaxHiddenCells; };
  for (const HiddenFacade& f : facades) f.validate();
  for (const HiddenFacade& f : facades) {
    render::Material m;
    m.name = "hidden_facade";
    m.albedo = f.albedo;
    const int material = static_cast<int>(mesh.materials.size());
    mesh.materials.push_back(m);
    const Vector3d along = Vector3d::UnitY().cross(f.normal);
    const Vector3d foot = -f.offset * f.normal;  // the plane's point nearest the origin
    const auto at = [&](double a, double h) { return Vector3d(foot + a * along + h * Vector3d::UnitY()); };
    const int rows = std::max(1, static_cast<int>(std::ceil((f.top_m - f.bottom_m) / o.cell_m)));
    const double cell_up = (f.top_m - f.bottom_m) / rows;
    const auto add_cell = [&](double a0, double a1, int j) {
      const double h0 = f.bottom_m + j * cell_up, h1 = h0 + cell_up;
      const Vector3d p00 = at(a0, h0), p10 = at(a1, h0), p11 = at(a1, h1), p01 = at(a0, h1);
      Eigen::Vector2d px;
      if (full() || in_view(p00, px) || in_view(p10, px) || in_view(p11, px) || in_view(p01, px) ||
          in_view(0.25 * (p00 + p10 + p11 + p01), px))
        return;
      // Counter-clockwise seen from the side the facade faces.
      if (along.cross(Vector3d::UnitY()).dot(f.normal) > 0)
        render::add_quad(mesh, p00.cast<float>(), p10.cast<float>(), p11.cast<float>(), p01.cast<float>(), material, 1.f);
      else
        render::add_quad(mesh, p00.cast<float>(), p01.cast<float>(), p11.cast<float>(), p10.cast<float>(), material, 1.f);
    };
    // Columns of cells are marched outwards from the seen extent both ways.
    // Each row stops where the photo sees through it (the sky above a lower
    // building, the street beyond a side wall), and a row stops where the
    // row below it stopped: a facade stands on the ground.
    const int seen_columns = std::max(1, static_cast<int>(std::ceil((f.seen_max - f.seen_min) / o.cell_m)));
    const double seen_cell = (f.seen_max - f.seen_min) / seen_columns;
    for (int i = 0; i < seen_columns && !full(); ++i)
      for (int j = 0; j < rows; ++j) add_cell(f.seen_min + i * seen_cell, f.seen_min + (i + 1) * seen_cell, j);
    for (const double direction : {1.0, -1.0}) {
      std::vector<bool> alive(rows, true);
      const double start = direction > 0 ? f.seen_max : f.seen_min, end = direction > 0 ? f.along_max : f.along_min;
      for (double a = start; direction * (end - a) > 0 && !full(); a += direction * o.cell_m) {
        bool any = false;
        for (int j = 0; j < rows; ++j) {
          alive[j] = alive[j] && (j == 0 || alive[j - 1]) &&
                     !in_free_space(at(a + direction * 0.5 * o.cell_m, f.bottom_m + (j + 0.5) * cell_up));
          if (!alive[j]) continue;
          any = true;
          add_cell(std::min(a, a + direction * o.cell_m), std::max(a, a + direction * o.cell_m), j);
        }
        if (!any) break;
      }
    }
  }
  return mesh;
}

}  // namespace propcam::inference
