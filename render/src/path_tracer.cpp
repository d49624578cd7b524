#include "propcam/render/path_tracer.h"

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

#include "sampling.h"

namespace propcam::render {
namespace {

using detail::Bsdf;
using detail::Frame;
using detail::Rng;

constexpr float kInfinity = std::numeric_limits<float>::infinity();
// Ray origins are pushed off surfaces by this fraction of their distance from
// the world origin (plus an absolute floor) to avoid self-intersection.
constexpr float kRayOffsetRelative = 1e-4f;
constexpr float kRayOffsetAbsolute = 1e-4f;
// Shadow rays stop this fraction short of the light so they do not hit it.
constexpr float kShadowShortening = 1e-3f;
constexpr int kRussianRouletteStartBounce = 2;
constexpr float kMaxSurvivalProbability = 0.95f;
// Sample contributions are clamped to this luminance so a rare caustic path
// cannot produce a white fleck (bias traded for variance, as in production renderers).
constexpr float kMaxSampleLuminance = 64.f;
// Light a prop adds to the photo's surfaces (bounce, reflected highlights,
// caustics) is clamped per sample to this luminance, about the photo's white:
// at interactive sample counts, a rare path from a floor pixel via a mirror
// ball to a lamp otherwise shows as a white speck far from the prop.
constexpr float kMaxBackgroundGainLuminance = 1.f;

Eigen::Vector3f offset_origin(const Eigen::Vector3f& p, const Eigen::Vector3f& normal) {
  return p + normal * (kRayOffsetAbsolute + kRayOffsetRelative * p.cwiseAbs().maxCoeff());
}

struct PathResult {
  Eigen::Vector3f radiance = Eigen::Vector3f::Zero();
  bool touched_prop = false;  // a prop changed this path (hit, or blocked a shadow ray)
  bool prop_primary = false;  // the camera ray hit a prop
  uint64_t rays = 0;
};

class PathIntegrator {
 public:
  PathIntegrator(const Scene& scene, const LightRig& lights, int max_bounces)
      : scene_(scene), lights_(lights), max_bounces_(max_bounces) {}

  PathResult trace(Eigen::Vector3f origin, Eigen::Vector3f direction, Rng& rng, bool with_props) const {
    PathResult result;
    Eigen::Vector3f throughput = Eigen::Vector3f::Ones();
    float previous_bsdf_pdf = 0.f;
    for (int bounce = 0;; ++bounce) {
      RayHit hit;
      ++result.rays;
      if (!scene_.intersect(origin, direction, kInfinity, with_props, hit)) {
        if (lights_.environment) {
          const Eigen::Vector3f le = lights_.environment->radiance(direction);
          const float weight =
              bounce == 0 ? 1.f : detail::power_heuristic(previous_bsdf_pdf, lights_.environment->pdf(direction));
          result.radiance += throughput.cwiseProduct(le) * weight;
        }
        break;
      }
      const SurfacePoint sp = scene_.surface(hit, origin, direction);
      if (sp.layer == Layer::Prop) {
        result.touched_prop = true;
        if (bounce == 0) result.prop_primary = true;
      }
      if (sp.material->type == Material::Type::Emissive) {
        // Emitters are sampled by next-event estimation; count them only when seen directly.
        if (bounce == 0) result.radiance += throughput.cwiseProduct(sp.material->emission);
        break;
      }
      if (bounce >= max_bounces_) break;

      const Frame frame(sp.shading_normal);
      const Eigen::Vector3f wo = frame.to_local(-direction);
      const Bsdf bsdf(*sp.material, sp.albedo);
      const Eigen::Vector3f shadow_origin = offset_origin(sp.position, sp.geometric_normal);
      result.radiance += throughput.cwiseProduct(direct_light(sp, frame, wo, bsdf, shadow_origin, rng,
                                                             with_props, result));

      Eigen::Vector3f wi_local;
      const float u0 = rng.uniform(), u1 = rng.uniform(), u2 = rng.uniform();
      if (!bsdf.sample(wo, u0, u1, u2, wi_local)) break;
      const float pdf = bsdf.pdf(wo, wi_local);
      if (!(pdf > 0.f)) break;
      const Eigen::Vector3f wi = frame.to_world(wi_local);
      if (wi.dot(sp.geometric_normal) <= 0.f) break;  // shading normal sent it below the surface
      throughput = throughput.cwiseProduct(bsdf.eval(wo, wi_local)) * (wi_local.z() / pdf);
      previous_bsdf_pdf = pdf;
      if (bounce + 1 >= kRussianRouletteStartBounce) {
        const float survive = std::min(kMaxSurvivalProbability, throughput.maxCoeff());
        if (rng.uniform() >= survive) break;
        throughput /= survive;
      }
      if (!throughput.allFinite()) break;
      origin = shadow_origin;
      direction = wi;
    }
    const float lum = 0.2126f * result.radiance.x() + 0.7152f * result.radiance.y() + 0.0722f * result.radiance.z();
    if (!result.radiance.allFinite()) result.radiance.setZero();
    else if (lum > kMaxSampleLuminance) result.radiance *= kMaxSampleLuminance / lum;
    return result;
  }

 private:
  // True when the segment is blocked. In the world with props, a block that
  // exists only because of a prop marks the path as touched.
  bool shadowed(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float distance, bool with_props,
                PathResult& result) const {
    ++result.rays;
    if (!scene_.occluded(origin, direction, distance, with_props)) return false;
    if (with_props && !result.touched_prop) {
      ++result.rays;
      if (!scene_.occluded(origin, direction, distance, false)) result.touched_prop = true;
    }
    return true;
  }

  Eigen::Vector3f direct_light(const SurfacePoint& sp, const Frame& frame, const Eigen::Vector3f& wo,
                               const Bsdf& bsdf, const Eigen::Vector3f& shadow_origin, Rng& rng, bool with_props,
                               PathResult& result) const {
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    for (const AreaLight& light : lights_.area_lights) {
      const float s = rng.uniform(), t = rng.uniform();
      const Eigen::Vector3f point = light.corner + s * light.edge_u + t * light.edge_v;
      Eigen::Vector3f to_light = point - shadow_origin;
      const float dist2 = to_light.squaredNorm();
      if (dist2 <= 1e-12f) continue;
      const float dist = std::sqrt(dist2);
      to_light /= dist;
      const float cos_light = -to_light.dot(light.normal());
      if (cos_light <= 0.f) continue;
      const Eigen::Vector3f wi = frame.to_local(to_light);
      if (wi.z() <= 0.f || to_light.dot(sp.geometric_normal) <= 0.f) continue;
      const Eigen::Vector3f f = bsdf.eval(wo, wi);
      if (f.isZero()) continue;
      if (shadowed(shadow_origin, to_light, dist * (1.f - kShadowShortening), with_props, result)) continue;
      sum += f.cwiseProduct(light.radiance) * (wi.z() * cos_light * light.area() / dist2);
    }
    if (lights_.environment) {
      float pdf = 0.f;
      const Eigen::Vector3f dir = lights_.environment->sample(rng.uniform(), rng.uniform(), pdf);
      const Eigen::Vector3f wi = frame.to_local(dir);
      if (pdf > 0.f && wi.z() > 0.f && dir.dot(sp.geometric_normal) > 0.f) {
        const Eigen::Vector3f f = bsdf.eval(wo, wi);
        if (!f.isZero() && !shadowed(shadow_origin, dir, kInfinity, with_props, result)) {
          const float weight = detail::power_heuristic(pdf, bsdf.pdf(wo, wi));
          sum += f.cwiseProduct(lights_.environment->radiance(dir)) * (wi.z() * weight / pdf);
        }
      }
    }
    return sum;
  }

  const Scene& scene_;
  const LightRig& lights_;
  int max_bounces_;
};

// Runs `render_tile(x0, y0, x1, y1)` over the image in tiles on worker threads.
template <typename TileFn>
void for_each_tile(int width, int height, const RenderSettings& settings, TileFn&& render_tile) {
  const int tile = std::max(4, settings.tile_size);
  const int tiles_x = (width + tile - 1) / tile, tiles_y = (height + tile - 1) / tile;
  const int total = tiles_x * tiles_y;
  std::atomic<int> next{0};
  std::atomic<int> done{0};
  std::mutex progress_mutex;
  int threads = settings.threads > 0 ? settings.threads : static_cast<int>(std::thread::hardware_concurrency());
  threads = std::clamp(threads, 1, std::max(1, total));
  auto worker = [&] {
    for (int index; (index = next.fetch_add(1)) < total;) {
      const int tx = index % tiles_x, ty = index / tiles_x;
      render_tile(tx * tile, ty * tile, std::min(width, (tx + 1) * tile), std::min(height, (ty + 1) * tile));
      const int finished = done.fetch_add(1) + 1;
      if (settings.progress) {
        std::lock_guard lock(progress_mutex);
        settings.progress(static_cast<double>(finished) / total);
      }
    }
  };
  std::vector<std::jthread> pool;
  for (int i = 1; i < threads; ++i) pool.emplace_back(worker);
  worker();
}

void check_inputs(const Scene& scene, const PinholeCamera& camera, const RenderSettings& settings) {
  (void)scene;
  if (camera.width <= 0 || camera.height <= 0) throw std::invalid_argument("render: camera has no pixels");
  if (!(camera.fx > 0.0 && camera.fy > 0.0) || !std::isfinite(camera.cx) || !std::isfinite(camera.cy))
    throw std::invalid_argument("render: invalid camera intrinsics");
  if (settings.samples_per_pixel <= 0) throw std::invalid_argument("render: samples_per_pixel must be positive");
  if (settings.max_bounces < 0) throw std::invalid_argument("render: max_bounces must be >= 0");
}

struct CameraRay {
  Eigen::Vector3f origin, direction;
};

CameraRay jittered_camera_ray(const PinholeCamera& camera, int x, int y, Rng& rng) {
  const double u = x + rng.uniform() - 0.5, v = y + rng.uniform() - 0.5;
  return {camera.center_world.cast<float>(), camera.ray_direction(u, v).cast<float>()};
}

uint64_t pixel_stream(const PinholeCamera& camera, int x, int y) {
  return static_cast<uint64_t>(y) * static_cast<uint64_t>(camera.width) + static_cast<uint64_t>(x);
}

}  // namespace

cv::Mat render_image(const Scene& scene, const PinholeCamera& camera, const LightRig& lights,
                     const RenderSettings& settings, RenderStats* stats) {
  check_inputs(scene, camera, settings);
  const auto start = std::chrono::steady_clock::now();
  cv::Mat image(camera.height, camera.width, CV_32FC3, cv::Scalar::all(0));
  const PathIntegrator integrator(scene, lights, settings.max_bounces);
  std::atomic<uint64_t> rays{0};
  for_each_tile(camera.width, camera.height, settings, [&](int x0, int y0, int x1, int y1) {
    uint64_t tile_rays = 0;
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) {
        Rng rng(detail::mix_seed(settings.seed, 0), pixel_stream(camera, x, y));
        Eigen::Vector3f sum = Eigen::Vector3f::Zero();
        for (int s = 0; s < settings.samples_per_pixel; ++s) {
          const CameraRay ray = jittered_camera_ray(camera, x, y, rng);
          const PathResult path = integrator.trace(ray.origin, ray.direction, rng, true);
          sum += path.radiance;
          tile_rays += path.rays;
        }
        sum /= static_cast<float>(settings.samples_per_pixel);
        image.at<cv::Vec3f>(y, x) = cv::Vec3f(sum.x(), sum.y(), sum.z());
      }
    rays += tile_rays;
  });
  if (stats) {
    stats->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    stats->camera_samples = static_cast<uint64_t>(camera.width) * camera.height * settings.samples_per_pixel;
    stats->rays = rays;
  }
  return image;
}

PrimaryBuffers render_primary_buffers(const Scene& scene, const PinholeCamera& camera, bool with_props) {
  PrimaryBuffers out;
  out.depth = cv::Mat(camera.height, camera.width, CV_32F, cv::Scalar(0));
  out.albedo = cv::Mat(camera.height, camera.width, CV_32FC3, cv::Scalar::all(0));
  out.normal = cv::Mat(camera.height, camera.width, CV_32FC3, cv::Scalar::all(0));
  out.prop_coverage = cv::Mat(camera.height, camera.width, CV_8U, cv::Scalar(0));
  const Eigen::Vector3f forward = (camera.R_world_from_cam * Eigen::Vector3d::UnitZ()).cast<float>();
  const Eigen::Vector3f origin = camera.center_world.cast<float>();
  for (int y = 0; y < camera.height; ++y)
    for (int x = 0; x < camera.width; ++x) {
      const Eigen::Vector3f dir = camera.ray_direction(x, y).cast<float>();
      RayHit hit;
      if (!scene.intersect(origin, dir, kInfinity, with_props, hit)) continue;
      const SurfacePoint sp = scene.surface(hit, origin, dir);
      out.depth.at<float>(y, x) = hit.t * dir.dot(forward);
      out.albedo.at<cv::Vec3f>(y, x) = {sp.albedo.x(), sp.albedo.y(), sp.albedo.z()};
      out.normal.at<cv::Vec3f>(y, x) = {sp.shading_normal.x(), sp.shading_normal.y(), sp.shading_normal.z()};
      if (sp.layer == Layer::Prop) out.prop_coverage.at<uint8_t>(y, x) = 255;
    }
  return out;
}

namespace {

// The per-sample change of one differential sample (see render_differential).
void differential_sample(const PathIntegrator& integrator, const PinholeCamera& camera, uint64_t seed, int x, int y,
                         int sample, DifferentialPixel& pixel) {
  Rng rng(detail::mix_seed(seed, static_cast<uint64_t>(sample) + 1), pixel_stream(camera, x, y));
  const CameraRay ray = jittered_camera_ray(camera, x, y, rng);
  // Both worlds consume the same random numbers: where the prop does not
  // interfere, the two paths are identical and their difference is exactly 0.
  Rng rng_without = rng;
  const PathResult with_prop = integrator.trace(ray.origin, ray.direction, rng, true);
  pixel.rays += with_prop.rays;
  ++pixel.samples;
  Eigen::Vector3f delta = Eigen::Vector3f::Zero();
  if (with_prop.prop_primary) {
    ++pixel.prop_samples;
    delta = with_prop.radiance;
  } else if (with_prop.touched_prop) {
    const PathResult without = integrator.trace(ray.origin, ray.direction, rng_without, false);
    pixel.rays += without.rays;
    ++pixel.second_paths;
    delta = with_prop.radiance - without.radiance;
    const float gain = 0.2126f * delta.x() + 0.7152f * delta.y() + 0.0722f * delta.z();
    if (gain > kMaxBackgroundGainLuminance) delta *= kMaxBackgroundGainLuminance / gain;
  } else {
    ++pixel.untouched;
    return;
  }
  pixel.change_sum += delta;
  const double lum = 0.2126 * delta.x() + 0.7152 * delta.y() + 0.0722 * delta.z();
  pixel.change_luminance_sq_sum += lum * lum;
}

}  // namespace

void accumulate_differential_pixel(const Scene& scene, const PinholeCamera& camera, const LightRig& lights,
                                   const RenderSettings& settings, int x, int y, int first_sample, int count,
                                   DifferentialPixel& pixel) {
  const PathIntegrator integrator(scene, lights, settings.max_bounces);
  for (int s = first_sample; s < first_sample + count; ++s)
    differential_sample(integrator, camera, settings.seed, x, y, s, pixel);
}

DifferentialRender render_differential(const Scene& scene, const PinholeCamera& camera, const LightRig& lights,
                                       const RenderSettings& settings) {
  check_inputs(scene, camera, settings);
  const auto start = std::chrono::steady_clock::now();
  DifferentialRender out;
  out.coverage = cv::Mat(camera.height, camera.width, CV_32F, cv::Scalar(0));
  out.change = cv::Mat(camera.height, camera.width, CV_32FC3, cv::Scalar::all(0));
  const PathIntegrator integrator(scene, lights, settings.max_bounces);
  std::atomic<uint64_t> rays{0}, second_paths{0}, untouched{0};
  for_each_tile(camera.width, camera.height, settings, [&](int x0, int y0, int x1, int y1) {
    uint64_t tile_rays = 0, tile_second = 0, tile_untouched = 0;
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) {
        DifferentialPixel pixel;
        for (int s = 0; s < settings.samples_per_pixel; ++s)
          differential_sample(integrator, camera, settings.seed, x, y, s, pixel);
        const float inv = 1.f / static_cast<float>(settings.samples_per_pixel);
        out.coverage.at<float>(y, x) = pixel.prop_samples * inv;
        out.change.at<cv::Vec3f>(y, x) = cv::Vec3f(pixel.change_sum.x(), pixel.change_sum.y(), pixel.change_sum.z()) * inv;
        tile_rays += pixel.rays;
        tile_second += pixel.second_paths;
        tile_untouched += pixel.untouched;
      }
    rays += tile_rays;
    second_paths += tile_second;
    untouched += tile_untouched;
  });
  out.stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  out.stats.camera_samples = static_cast<uint64_t>(camera.width) * camera.height * settings.samples_per_pixel;
  out.stats.rays = rays;
  out.stats.paths_without_prop = second_paths;
  out.stats.paths_prop_untouched = untouched;
  return out;
}

cv::Mat composite_differential(const cv::Mat& photo_linear, const DifferentialRender& render) {
  if (photo_linear.type() != CV_32FC3 || photo_linear.size() != render.change.size())
    throw std::invalid_argument("composite: photo must be CV_32FC3 of the render's size");
  cv::Mat out(photo_linear.size(), CV_32FC3);
  for (int y = 0; y < out.rows; ++y) {
    const auto* photo = photo_linear.ptr<cv::Vec3f>(y);
    const auto* change = render.change.ptr<cv::Vec3f>(y);
    const auto* mask = render.coverage.ptr<float>(y);
    auto* o = out.ptr<cv::Vec3f>(y);
    for (int x = 0; x < out.cols; ++x)
      for (int c = 0; c < 3; ++c) o[x][c] = std::max(0.f, (1.f - mask[x]) * photo[x][c] + change[x][c]);
  }
  return out;
}

}  // namespace propcam::render
