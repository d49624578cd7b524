// Light sources: one-sided area quads (sources seen in the photo, ceiling
// panels) and an environment map (light from outside the frame).
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <memory>
#include <string>
#include <vector>

namespace propcam::render {

// Parallelogram corner + s*edge_u + t*edge_v, s,t in [0,1]; emits radiance on
// the side of edge_u x edge_v.
struct AreaLight {
  Eigen::Vector3f corner = Eigen::Vector3f::Zero();
  Eigen::Vector3f edge_u = Eigen::Vector3f::UnitX();
  Eigen::Vector3f edge_v = Eigen::Vector3f::UnitZ();
  Eigen::Vector3f radiance = Eigen::Vector3f::Ones();

  Eigen::Vector3f normal() const { return edge_u.cross(edge_v).normalized(); }
  float area() const { return edge_u.cross(edge_v).norm(); }
  Eigen::Vector3f centre() const { return corner + 0.5f * (edge_u + edge_v); }
};

// Equirectangular environment in world coordinates (Y up). Column 0 is the
// direction -Z, columns increase toward +X (phi = atan2(x, -z)); row 0 is +Y.
// Importance sampled in proportion to luminance times sin(theta).
class EnvironmentLight {
 public:
  EnvironmentLight() = default;
  // `latlong` is CV_32FC3 linear RGB; negative and non-finite texels are clamped to 0.
  explicit EnvironmentLight(const cv::Mat& latlong, Eigen::Vector3f scale = Eigen::Vector3f::Ones());

  bool valid() const { return !image_.empty(); }
  const cv::Mat& image() const { return image_; }
  Eigen::Vector3f scale() const { return scale_; }
  void set_scale(const Eigen::Vector3f& scale) { scale_ = scale; }

  Eigen::Vector3f radiance(const Eigen::Vector3f& direction) const;
  // Samples a direction from two uniform numbers; returns its solid-angle pdf.
  Eigen::Vector3f sample(float u1, float u2, float& pdf) const;
  float pdf(const Eigen::Vector3f& direction) const;

  static Eigen::Vector2f direction_to_uv(const Eigen::Vector3f& d);  // [0,1)^2
  static Eigen::Vector3f uv_to_direction(float u, float v);

 private:
  cv::Mat image_;
  Eigen::Vector3f scale_ = Eigen::Vector3f::Ones();
  std::vector<float> marginal_cdf_;     // over rows, size rows+1
  std::vector<float> conditional_cdf_;  // per row over columns, rows*(cols+1)
  std::vector<float> row_weight_;
  float total_weight_ = 0.f;
};

struct LightRig {
  std::vector<AreaLight> area_lights;
  std::shared_ptr<EnvironmentLight> environment;  // may be null

  int count() const { return static_cast<int>(area_lights.size()) + (environment ? 1 : 0); }
  // A rig holding only light `index` (area lights first, then the environment).
  LightRig only(int index) const;
};

}  // namespace propcam::render
