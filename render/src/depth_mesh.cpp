#include "propcam/render/depth_mesh.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace propcam::render {

Mesh mesh_from_depth(const cv::Mat& depth, const cv::Mat& albedo, const PinholeCamera& camera,
                     const DepthMeshOptions& options) {
  if (depth.type() != CV_32F || albedo.type() != CV_32FC3 || depth.size() != albedo.size())
    throw std::invalid_argument("mesh_from_depth: need CV_32F depth and CV_32FC3 albedo of one size");
  if (depth.cols != camera.width || depth.rows != camera.height)
    throw std::invalid_argument("mesh_from_depth: depth size differs from the camera's");
  const int step = std::max(1, options.step_pixels);
  // Grid vertices on pixel centres, always including the last row and column.
  std::vector<int> xs, ys;
  for (int x = 0; x < depth.cols; x += step) xs.push_back(x);
  if (xs.back() != depth.cols - 1) xs.push_back(depth.cols - 1);
  for (int y = 0; y < depth.rows; y += step) ys.push_back(y);
  if (ys.back() != depth.rows - 1) ys.push_back(depth.rows - 1);

  Mesh mesh;
  Material material;
  material.name = "photo";
  material.albedo = Eigen::Vector3f::Ones();
  material.texture = std::make_shared<const cv::Mat>(albedo.clone());
  mesh.materials.push_back(material);

  const int gw = static_cast<int>(xs.size()), gh = static_cast<int>(ys.size());
  std::vector<int> index(static_cast<size_t>(gw) * gh, -1);
  std::vector<float> vertex_depth;
  for (int j = 0; j < gh; ++j)
    for (int i = 0; i < gw; ++i) {
      // Vertices sit at pixel corners' centres; extend the border ones half a
      // pixel so the mesh covers the whole image.
      const double u = xs[i] + (i == 0 ? -0.5 : (i == gw - 1 ? 0.5 : 0.0));
      const double v = ys[j] + (j == 0 ? -0.5 : (j == gh - 1 ? 0.5 : 0.0));
      const float d = depth.at<float>(ys[j], xs[i]);
      if (!(d > 0.f) || !(d < kSkyDepthM)) continue;
      const Eigen::Vector3d dir_cam((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0);
      const Eigen::Vector3d p = camera.center_world + camera.R_world_from_cam * (dir_cam * d);
      index[static_cast<size_t>(j) * gw + i] = static_cast<int>(mesh.positions.size());
      mesh.positions.push_back(p.cast<float>());
      mesh.uvs.emplace_back(static_cast<float>((u + 0.5) / depth.cols), static_cast<float>((v + 0.5) / depth.rows));
      vertex_depth.push_back(d);
    }
  auto add_triangle = [&](int a, int b, int c) {
    if (a < 0 || b < 0 || c < 0) return;
    const float lo = std::min({vertex_depth[a], vertex_depth[b], vertex_depth[c]});
    const float hi = std::max({vertex_depth[a], vertex_depth[b], vertex_depth[c]});
    if (hi > lo * options.max_depth_ratio) return;
    mesh.triangles.emplace_back(a, b, c);
    mesh.material_ids.push_back(0);
  };
  for (int j = 0; j + 1 < gh; ++j)
    for (int i = 0; i + 1 < gw; ++i) {
      const int a = index[static_cast<size_t>(j) * gw + i], b = index[static_cast<size_t>(j) * gw + i + 1];
      const int c = index[static_cast<size_t>(j + 1) * gw + i], d = index[static_cast<size_t>(j + 1) * gw + i + 1];
      add_triangle(a, c, b);
      add_triangle(b, c, d);
    }
  return mesh;
}

}  // namespace propcam::render
