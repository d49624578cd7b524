// A street our renderer lights with a known sun and sky (blocks on a ground
// plane cast the shadows), for the sun search's tests (sun_from_shadows.h).
#pragma once

#include <cmath>
#include <memory>
#include <numbers>
#include <opencv2/core.hpp>

#include "propcam/render/lights.h"
#include "propcam/render/mesh_shapes.h"
#include "propcam/render/path_tracer.h"

namespace propcam::inference::testing {

using Eigen::Vector3d;
using Eigen::Vector3f;

constexpr double kSkyRadiance = 0.35;
constexpr double kSunIrradiance = 3.0;

inline Vector3d sun_at(double elevation_deg, double azimuth_deg) {
  const double e = elevation_deg * std::numbers::pi / 180, a = azimuth_deg * std::numbers::pi / 180;
  return {std::cos(e) * std::sin(a), std::sin(e), std::cos(e) * std::cos(a)};
}

inline double angle_deg(const Vector3d& a, const Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180 / std::numbers::pi;
}

// A uniform sky over the upper hemisphere, dark ground below.
inline std::shared_ptr<render::EnvironmentLight> sky() {
  cv::Mat img(32, 64, CV_32FC3);
  for (int y = 0; y < img.rows; ++y)
    img.row(y).setTo(y < img.rows / 2 ? cv::Scalar(kSkyRadiance, kSkyRadiance, kSkyRadiance) : cv::Scalar(0.02, 0.02, 0.02));
  return std::make_shared<render::EnvironmentLight>(img);
}

struct Street {
  render::Scene scene;
  render::PinholeCamera camera;
  cv::Mat photo, albedo, sky_basis, usable;
};

// Ground and three blocks seen from 1.6 m, looking down the -Z axis.
// `with_blocks` false: the bare ground, where no sun casts a shadow.
inline std::unique_ptr<Street> make_street(const Vector3d& sun, double sun_irradiance, bool with_blocks = true) {
  auto s = std::make_unique<Street>();
  render::Mesh mesh;
  render::Material ground, wall;
  ground.albedo = {0.3f, 0.3f, 0.3f};
  wall.albedo = {0.55f, 0.5f, 0.45f};
  mesh.materials = {ground, wall};
  render::add_quad(mesh, {-40, 0, 20}, {40, 0, 20}, {40, 0, -60}, {-40, 0, -60}, 0, 1.f);
  if (with_blocks) {
    render::add_box(mesh, {-9, 0, -30}, {-4, 9, -8}, 1);
    render::add_box(mesh, {4, 0, -26}, {10, 6, -6}, 1);
    render::add_box(mesh, {-2, 0, -40}, {3, 12, -34}, 1);
  }
  s->scene.add_mesh(mesh, render::Layer::Background);
  s->scene.commit();
  s->camera = render::pinhole_with_fov(160, 120, 70);
  s->camera.R_world_from_cam = render::rotation_from_yaw_pitch_roll(0.1, -0.12, 0);
  s->camera.center_world = {0, 1.6, 2};
  render::LightRig rig;
  render::SunLight light;
  light.direction = sun.cast<float>();
  light.irradiance = Vector3f::Constant(static_cast<float>(sun_irradiance));
  rig.suns.push_back(light);
  rig.environment = sky();
  render::RenderSettings settings;
  settings.samples_per_pixel = 32;
  settings.max_bounces = 2;
  s->photo = render::render_image(s->scene, s->camera, rig, settings);
  s->albedo = render::render_primary_buffers(s->scene, s->camera, false).albedo;
  render::LightRig sky_only;
  sky_only.environment = rig.environment;
  settings.samples_per_pixel = 8;
  s->sky_basis = render::render_background_light_images(s->scene, s->camera, sky_only, settings).front();
  const cv::Mat depth = render::render_primary_buffers(s->scene, s->camera, false).depth;
  s->usable = depth > 0;
  return s;
}

}  // namespace propcam::inference::testing
