#include "worlds/light_probe.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <stdexcept>
#include <vector>

#include "propcam/render/camera.h"
#include "propcam/render/path_tracer.h"

namespace propcam::firmware {
namespace {

double luminance(const Eigen::Vector3f& c) { return 0.2126 * c.x() + 0.7152 * c.y() + 0.0722 * c.z(); }
double luminance(const cv::Vec3f& c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

// Seen lights are scaled so that the brightest is at most this luminance for
// the face renders: well under the path tracer's per-sample clamp (64), with
// room for a light and the environment behind it in one sample.
constexpr double kMaxSeenLuminance = 16.0;
// Bounces of the face renders: the first surface's direct light and one more.
constexpr int kProbeBounces = 2;

// The six cube faces: forward and down, columns of R_world_from_cam (right = down x forward).
render::PinholeCamera face_camera(int face, int n, const Eigen::Vector3f& point) {
  static const std::array<std::pair<Eigen::Vector3d, Eigen::Vector3d>, 6> kFaces = {{
      {Eigen::Vector3d::UnitX(), -Eigen::Vector3d::UnitY()},
      {-Eigen::Vector3d::UnitX(), -Eigen::Vector3d::UnitY()},
      {Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ()},
      {-Eigen::Vector3d::UnitY(), -Eigen::Vector3d::UnitZ()},
      {Eigen::Vector3d::UnitZ(), -Eigen::Vector3d::UnitY()},
      {-Eigen::Vector3d::UnitZ(), -Eigen::Vector3d::UnitY()},
  }};
  const auto& [forward, down] = kFaces[face];
  render::PinholeCamera cam;
  cam.width = cam.height = n;
  cam.fx = cam.fy = 0.5 * n;
  cam.cx = cam.cy = 0.5 * (n - 1);
  cam.R_world_from_cam.col(0) = down.cross(forward);
  cam.R_world_from_cam.col(1) = down;
  cam.R_world_from_cam.col(2) = forward;
  cam.center_world = point.cast<double>();
  return cam;
}

// Solid angle of the rectangle [a0,a1] x [b0,b1] on the plane at distance 1.
double rectangle_solid_angle(double a0, double a1, double b0, double b1) {
  const auto F = [](double a, double b) { return std::atan(a * b / std::sqrt(1.0 + a * a + b * b)); };
  return F(a1, b1) - F(a0, b1) - F(a1, b0) + F(a0, b0);
}

// Moments of one face image (luminance per pixel, times `scale`), each pixel weighted by its exact solid angle.
void add_face(LightMoments& m, const cv::Mat& image, const render::PinholeCamera& cam, double scale, double weight) {
  const int n = image.cols;
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const double L = luminance(image.at<cv::Vec3f>(y, x)) * scale * weight;
      if (!std::isfinite(L) || L == 0) continue;
      const double a0 = (2.0 * x - n) / n, a1 = (2.0 * x + 2.0 - n) / n;
      const double b0 = (2.0 * y - n) / n, b1 = (2.0 * y + 2.0 - n) / n;
      const double omega = rectangle_solid_angle(a0, a1, b0, b1);
      const Eigen::Vector3d w = cam.ray_direction(x, y);
      m.vector += L * omega * w;
      m.irradiance_up += L * omega * std::max(0.0, w.y());
      m.total += L * omega;
    }
}

// Light samples per area or sphere light for its directly seen part (a
// jittered kLightGrid x kLightGrid grid over the light's sampling domain).
constexpr int kLightGrid = 24;

// What reaches `point` straight from one light, by light sampling with shadow rays.
template <typename Light>
void add_direct(LightMoments& m, const render::Scene& scene, const Light& light, const Eigen::Vector3f& point,
                std::mt19937_64& rng) {
  std::uniform_real_distribution<float> jitter(0.f, 1.f);
  const double w = 1.0 / (kLightGrid * kLightGrid);
  for (int i = 0; i < kLightGrid; ++i)
    for (int j = 0; j < kLightGrid; ++j) {
      const float u1 = (i + jitter(rng)) / kLightGrid, u2 = (j + jitter(rng)) / kLightGrid;
      const render::LightSample ls = light.sample(point, u1, u2);
      if (!(ls.pdf > 0.f) || !std::isfinite(ls.pdf) || !ls.direction.allFinite()) continue;
      const double L = luminance(ls.radiance);
      if (!(L > 0) || !std::isfinite(L)) continue;
      const float distance = std::isinf(ls.distance) ? std::numeric_limits<float>::infinity() : ls.distance * (1.f - 1e-3f);
      if (scene.occluded(point, ls.direction, distance, false)) continue;
      const Eigen::Vector3d d = ls.direction.cast<double>();
      const double e = L * w / ls.pdf;
      m.vector += e * d;
      m.irradiance_up += e * std::max(0.0, d.y());
      m.total += e;
    }
}

}  // namespace

LightMoments probe_light_moments(const render::Scene& scene, const render::LightRig& lights,
                                 const Eigen::Vector3f& point, int face_px, int spp, uint64_t seed) {
  if (face_px < 2) throw std::invalid_argument("probe_light_moments: face_px must be at least 2");
  if (spp < 1) throw std::invalid_argument("probe_light_moments: spp must be positive");
  if (!point.allFinite()) throw std::invalid_argument("probe_light_moments: the point is not finite");

  // The brightest light a face can see (or that lights a surface it sees),
  // so that the renders stay below the per-sample clamp.
  double brightest = 0;
  for (const auto& l : lights.area_lights) brightest = std::max(brightest, luminance(l.radiance));
  for (const auto& l : lights.sphere_lights)
    if (!l.prop_only) brightest = std::max(brightest, luminance(l.radiance));
  for (const auto& s : lights.suns) brightest = std::max(brightest, luminance(s.irradiance));
  for (const auto& l : lights.disc_lights) brightest = std::max(brightest, luminance(l.radiance));
  // A point is never seen: like a sun, what counts is the irradiance it
  // gives (here at the probe point, as an estimate for surfaces near it).
  for (const auto& l : lights.point_lights)
    brightest = std::max(brightest, luminance(l.sample(point).radiance));
  if (lights.environment && lights.environment->valid()) {
    double max_texel = 0;
    const cv::Mat& image = lights.environment->image();
    for (auto it = image.begin<cv::Vec3f>(); it != image.end<cv::Vec3f>(); ++it)
      max_texel = std::max(max_texel, luminance(*it));
    brightest = std::max(brightest, max_texel * luminance(lights.environment->scale()));
  }
  if (!std::isfinite(brightest)) brightest = 0;
  const double scale = std::max(1.0, brightest / kMaxSeenLuminance);
  const float inv = static_cast<float>(1.0 / scale);
  render::LightRig rig = lights;
  for (auto& l : rig.area_lights) l.radiance *= inv;
  for (auto& l : rig.sphere_lights) l.radiance *= inv;
  for (auto& s : rig.suns) s.irradiance *= inv;
  for (auto& l : rig.disc_lights) l.radiance *= inv;
  for (auto& l : rig.point_lights) l.intensity *= inv;
  if (lights.environment) {
    auto env = std::make_shared<render::EnvironmentLight>(*lights.environment);
    env->set_scale(lights.environment->scale() * inv);
    rig.environment = env;
  }

  // Light reflected toward the point by the scene's surfaces: per sample,
  // a path of kProbeBounces minus the same camera ray's directly seen
  // emission (a render at 0 bounces from the same random stream), so lights
  // seen directly cancel exactly and only what surfaces send remains.
  render::RenderSettings settings;
  settings.samples_per_pixel = 1;
  settings.tile_size = std::max(4, std::min(32, face_px));
  render::RenderSettings direct_settings = settings;
  direct_settings.max_bounces = 0;
  settings.max_bounces = kProbeBounces;
  // The environment (and emissive surfaces) seen directly, past the scene's occluders.
  render::LightRig env_rig;
  env_rig.environment = rig.environment;
  env_rig.portals = rig.portals;
  render::RenderSettings env_settings = direct_settings;
  env_settings.samples_per_pixel = spp;

  LightMoments m;
  for (int face = 0; face < 6; ++face) {
    const render::PinholeCamera cam = face_camera(face, face_px, point);
    for (int s = 0; s < spp; ++s) {
      settings.seed = direct_settings.seed = seed * 1000003u + static_cast<uint64_t>(face * spp + s);
      const cv::Mat paths = render::render_background_image(scene, cam, rig, settings);
      const cv::Mat seen = render::render_background_image(scene, cam, rig, direct_settings);
      add_face(m, paths - seen, cam, scale, 1.0 / spp);
    }
    env_settings.seed = seed * 7919u + static_cast<uint64_t>(face);
    add_face(m, render::render_background_image(scene, cam, env_rig, env_settings), cam, scale, 1.0);
  }
  // Area, sphere, disc and point lights seen directly: light sampling with
  // shadow rays (a point's samples all agree: their mean is exact).
  std::mt19937_64 rng(seed);
  for (const auto& l : lights.area_lights)
    if (l.emits()) add_direct(m, scene, l, point, rng);
  for (const auto& l : lights.sphere_lights)
    if (l.emits() && !l.prop_only) add_direct(m, scene, l, point, rng);
  for (const auto& l : lights.disc_lights)
    if (l.emits()) add_direct(m, scene, l, point, rng);
  for (const auto& l : lights.point_lights)
    if (l.emits()) add_direct(m, scene, l, point, rng);
  // Suns: their discs, where the way to them is free.
  for (const auto& sun : lights.suns) {
    if (!sun.emits()) continue;
    const double E = luminance(sun.irradiance);
    if (!(E > 0) || !std::isfinite(E)) continue;
    const Eigen::Vector3f d = sun.direction.normalized();
    if (!lights.arrives_from_outside(point, d, sun.through_portals)) continue;  // a window's sun, not through one
    if (scene.occluded(point, d, std::numeric_limits<float>::infinity(), false)) continue;
    const Eigen::Vector3d w = d.cast<double>();
    m.vector += E * w;
    m.irradiance_up += E * std::max(0.0, w.y());
    m.total += E;
  }
  return m;
}

LightMoments latlong_light_moments(const cv::Mat& latlong) {
  if (latlong.empty() || latlong.type() != CV_32FC3)
    throw std::invalid_argument("latlong_light_moments: the panorama must be a non-empty CV_32FC3 image");
  const int rows = latlong.rows, cols = latlong.cols;
  const double pi = 3.14159265358979323846;
  LightMoments m;
  for (int y = 0; y < rows; ++y) {
    const double omega = (2.0 * pi / cols) * (std::cos(pi * y / rows) - std::cos(pi * (y + 1) / rows));
    const float v = (y + 0.5f) / rows;
    for (int x = 0; x < cols; ++x) {
      const cv::Vec3f c = latlong.at<cv::Vec3f>(y, x);
      cv::Vec3f clean;
      for (int k = 0; k < 3; ++k) clean[k] = std::isfinite(c[k]) && c[k] > 0.f ? c[k] : 0.f;
      const double L = luminance(clean);
      if (!(L > 0)) continue;
      const Eigen::Vector3d w = render::EnvironmentLight::uv_to_direction((x + 0.5f) / cols, v).cast<double>();
      m.vector += L * omega * w;
      m.irradiance_up += L * omega * std::max(0.0, w.y());
      m.total += L * omega;
    }
  }
  return m;
}

}  // namespace propcam::firmware
