#include "propcam/render/path_tracer.h"

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

#include "area_light_sampler.h"
#include "bsdf.h"
#include "emissive_lights.h"
#include "light_stand_ins.h"
#include "portal_sampler.h"
#include "sampler.h"
#include "sampling.h"

namespace propcam::render {
namespace {

using detail::Bsdf;
using detail::BsdfSample;
using detail::Frame;
using detail::SobolSampler;

constexpr float kInfinity = std::numeric_limits<float>::infinity();
// Ray origins are pushed off surfaces by this fraction of their distance from
// the world origin (plus an absolute floor) to avoid self-intersection.
constexpr float kRayOffsetRelative = 1e-4f;
constexpr float kRayOffsetAbsolute = 1e-4f;
// Shadow rays stop this fraction short of the light so they do not hit it.
constexpr float kShadowShortening = 1e-3f;
constexpr int kRussianRouletteStartBounce = 2;
// Russian roulette ends only paths whose throughput has fallen below this,
// with survival probability throughput / kRouletteThroughput. Side by side with
// Cycles (docs/renderer_vs_cycles.md) survival = throughput (pbrt's rule, capped
// at 0.95) or its square root (Cycles') added more variance than the rays it
// saved: in a box room the same error took 1.5x and 1.0x Cycles' time, this
// 0.5x. The bounce limit still ends every path.
constexpr float kRouletteThroughput = 0.1f;
// Sampler dimensions: the camera ray's pixel position, then per bounce one 2D
// draw per light (next-event estimation), the BSDF's lobe (1D) and direction
// (2D), and Russian roulette (1D).
constexpr int kCameraDimensions = 1;
constexpr int kBsdfAndRouletteDimensions = 3;
// Emissive triangles, when the scene has some to sample: which triangle (1D)
// and where on it (2D), after the rig's lights.
constexpr int kEmissiveDimensions = 2;
// Light a prop adds to the photo's surfaces (bounce, reflected highlights,
// caustics) is clamped per sample to this luminance, about the photo's white:
// at interactive sample counts, a rare path from a floor pixel via a mirror
// ball to a lamp otherwise shows as a white speck far from the prop.
constexpr float kMaxBackgroundGainLuminance = 1.f;

Eigen::Vector3f offset_origin(const Eigen::Vector3f& p, const Eigen::Vector3f& normal) {
  return p + normal * (kRayOffsetAbsolute + kRayOffsetRelative * p.cwiseAbs().maxCoeff());
}

// A light met at t_light counts as in front of a surface met at t_hit by the
// shadow rays' rule: blocked only by a surface nearer than the shortened distance.
bool light_in_front_of(float t_light, float t_hit) { return t_light * (1.f - kShadowShortening) < t_hit; }

// Surfaces whose reflection is sharp enough to focus light (caustics).
constexpr float kCausticMaxRoughness = 0.3f;

bool is_specular(const Material& m) {
  return (m.type == Material::Type::Metal || m.type == Material::Type::Dielectric) && m.roughness < kCausticMaxRoughness;
}

struct PathResult {
  Eigen::Vector3f radiance = Eigen::Vector3f::Zero();
  // With layers on: the radiance split by the light it came from (rig order,
  // then one slot for emissive surfaces outside the rig). Sums to `radiance`.
  std::vector<Eigen::Vector3f> per_light;
  bool touched_prop = false;  // a prop changed this path (hit, or blocked a shadow ray)
  bool prop_primary = false;  // the camera ray hit a prop
  uint64_t rays = 0;
};

class PathIntegrator {
 public:
  PathIntegrator(const Scene& scene, const LightRig& lights, const RenderSettings& settings, bool layers)
      : scene_(scene),
        lights_(lights),
        max_bounces_(settings.max_bounces),
        max_sample_luminance_(settings.max_sample_luminance > 0.f ? settings.max_sample_luminance : kInfinity),
        layers_(layers),
        caustics_(settings.caustics),
        prop_interreflection_(settings.prop_interreflection),
        area_samplers_(lights.area_lights.begin(), lights.area_lights.end()),
        portals_(lights.portals),
        sky_through_portals_(lights.environment && lights.environment->through_portals() && !portals_.empty()),
        emissive_(scene.emissive_lights()),
        sample_emissive_(!emissive_.empty() && !detail::rig_stands_for_every_emitter(lights, emissive_)) {}

  // The slot for emissive surfaces, after the rig's lights (LightRig order).
  int emissive_slot() const { return lights_.count(); }

  PathResult trace(Eigen::Vector3f origin, Eigen::Vector3f direction, SobolSampler& sampler, bool with_props) const {
    PathResult result;
    if (layers_) result.per_light.assign(lights_.count() + 1, Eigen::Vector3f::Zero());
    // Every contribution enters here, with the light it came from.
    Eigen::Vector3f throughput = Eigen::Vector3f::Ones();
    const auto add = [&](int light, const Eigen::Vector3f& value) {
      const Eigen::Vector3f v = throughput.cwiseProduct(value);
      result.radiance += v;
      if (layers_) result.per_light[light] += v;
    };
    bool after_background = false;  // the path has left a background surface
    // Product of eta^2 over refractions: Russian roulette looks at the
    // throughput without the n^2 radiance scaling that cancels on exit.
    float eta_scale = 1.f;
    float previous_bsdf_pdf = 0.f;
    // The last shading point and its normal: a BSDF-sampled ray that meets an
    // emissive triangle weighs itself against the density light sampling from
    // there had for it.
    Eigen::Vector3f previous_position = Eigen::Vector3f::Zero(), previous_normal = Eigen::Vector3f::Zero();
    const int dimensions_per_bounce =
        lights_.count() + (sample_emissive_ ? kEmissiveDimensions : 0) + kBsdfAndRouletteDimensions;
    for (int bounce = 0; bounce <= max_bounces_; ++bounce) {
      sampler.set_dimension(kCameraDimensions + bounce * dimensions_per_bounce);
      RayHit hit;
      ++result.rays;
      const bool found = scene_.intersect(origin, direction, kInfinity, with_props, hit);
      // Lights met by this ray before the surface: seen directly by the camera,
      // or found by BSDF sampling (MIS-weighted against light sampling).
      bool light_in_front = false;
      emitted_along(origin, direction, found ? hit.t : kInfinity, bounce == 0, previous_bsdf_pdf, with_props,
                    light_in_front, result, add);
      if (!found) break;
      const SurfacePoint sp = scene_.surface(hit, origin, direction);
      if (sp.layer == Layer::Prop) {
        result.touched_prop = true;
        if (bounce == 0) result.prop_primary = true;
        // Light the prop sends onto the photo's surfaces, when the plan skips it:
        // the path ends here (the prop still blocks, so shadows stay).
        if (after_background && (!prop_interreflection_ || (!caustics_ && is_specular(*sp.material)))) break;
      } else {
        after_background = true;
      }
      if (sp.material->type == Material::Type::Emissive) {
        // Unless a light of the rig stands in front of it (synthetic rooms'
        // panels): then that light stands for it and it is not counted twice.
        if (!light_in_front)
          add(emissive_slot(), sp.material->emission * emissive_hit_weight(hit, sp, bounce == 0, previous_position,
                                                                           previous_normal, previous_bsdf_pdf));
        break;
      }
      if (bounce >= max_bounces_) break;

      const Frame frame(sp.shading_normal);
      const Eigen::Vector3f wo = frame.to_local(-direction);
      const Bsdf bsdf(*sp.material, sp.albedo, sp.front_face);
      direct_light(sp, frame, wo, bsdf, sampler, with_props, result, add);

      BsdfSample bs;
      const float u0 = sampler.get1d();
      const Eigen::Vector2f u = sampler.get2d();
      if (!bsdf.sample(wo, u0, u.x(), u.y(), bs)) break;
      const Eigen::Vector3f wi = frame.to_world(bs.wi);
      const float cos_geometric = wi.dot(sp.geometric_normal);
      // The shading normal sent it to the other side of the actual surface.
      if (cos_geometric == 0.f || (cos_geometric > 0.f) != (bs.wi.z() > 0.f)) break;
      throughput = throughput.cwiseProduct(bs.f) * (std::abs(bs.wi.z()) / bs.pdf);
      if (bs.transmitted) eta_scale *= bsdf.eta() * bsdf.eta();
      previous_bsdf_pdf = bs.pdf;
      previous_position = sp.position;
      previous_normal = sp.shading_normal;
      if (bounce + 1 >= kRussianRouletteStartBounce) {
        const float survive = std::min(1.f, throughput.maxCoeff() * eta_scale / kRouletteThroughput);
        if (sampler.get1d() >= survive) break;
        throughput /= survive;
      }
      if (!throughput.allFinite()) break;
      origin = offset_origin(sp.position, cos_geometric > 0.f ? sp.geometric_normal : Eigen::Vector3f(-sp.geometric_normal));
      direction = wi;
    }
    const float lum = 0.2126f * result.radiance.x() + 0.7152f * result.radiance.y() + 0.0722f * result.radiance.z();
    float scale = 1.f;
    if (!result.radiance.allFinite()) scale = 0.f;
    else if (lum > max_sample_luminance_) scale = max_sample_luminance_ / lum;
    if (scale != 1.f) {
      result.radiance *= scale;
      for (auto& l : result.per_light) l = scale == 0.f || !l.allFinite() ? Eigen::Vector3f::Zero() : Eigen::Vector3f(l * scale);
    }
    return result;
  }

 private:
  // A light of the rig (area, sphere, disc) that the ray origin + t*direction
  // meets before t_hit, by emitted_along's rule: such a light stands for the
  // emissive surface behind it.
  bool rig_light_before(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float t_hit,
                        bool with_props) const {
    float t = 0.f, pdf = 0.f;
    const auto in_front = [&](float t_light) { return light_in_front_of(t_light, t_hit); };
    for (const detail::AreaLightSampler& light : area_samplers_)
      if (light.intersect(origin, direction, t, pdf) && in_front(t)) return true;
    for (const SphereLight& light : lights_.sphere_lights)
      if ((with_props || !light.prop_only) && light.intersect(origin, direction, t, pdf) && in_front(t)) return true;
    for (const DiscLight& light : lights_.disc_lights)
      if (light.intersect(origin, direction, t, pdf) && in_front(t)) return true;
    return false;
  }

  // The MIS weight of an emissive surface met by a ray: 1 for the camera's, or
  // where light sampling could not have chosen it; else the power heuristic
  // against the density next-event estimation had for it from the last vertex.
  float emissive_hit_weight(const RayHit& hit, const SurfacePoint& sp, bool camera,
                            const Eigen::Vector3f& from, const Eigen::Vector3f& from_normal, float bsdf_pdf) const {
    if (camera || !sample_emissive_) return 1.f;
    const int index = emissive_.index_of(hit.mesh, hit.triangle);
    if (index < 0) return 1.f;
    const Eigen::Vector3f to = sp.position - from;
    const float light_pdf = emissive_.pmf(from, from_normal, index) * emissive_.pdf(index, from, to, to.norm());
    return detail::power_heuristic(bsdf_pdf, light_pdf);
  }

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

  // Radiance of the lights the ray origin + t*direction meets before t_hit
  // (area, disc and sphere lights; suns and the environment when it escapes;
  // never a point light). `camera`: the ray is the camera's, weight 1, and
  // lights hidden from the camera are not seen (they still stand for an
  // emissive surface behind them); otherwise it was sampled from a BSDF with
  // density bsdf_pdf, weighted by the power heuristic.
  template <typename Add>
  void emitted_along(const Eigen::Vector3f& origin, const Eigen::Vector3f& direction, float t_hit, bool camera,
                     float bsdf_pdf, bool with_props, bool& light_in_front, PathResult& result, const Add& add) const {
    const auto weight = [&](float light_pdf) { return camera ? 1.f : detail::power_heuristic(bsdf_pdf, light_pdf); };
    const auto seen = [&](bool visible_to_camera) { return !camera || visible_to_camera; };
    float t = 0.f, light_pdf = 0.f;
    const auto in_front = [&](float t_light) { return light_in_front_of(t_light, t_hit); };
    int index = 0;
    for (const AreaLight& light : lights_.area_lights) {
      if (area_samplers_[index].intersect(origin, direction, t, light_pdf) && in_front(t)) {
        if (seen(light.visible_to_camera)) add(index, light.radiance * weight(light_pdf));
        light_in_front = true;
      }
      ++index;
    }
    for (const SphereLight& light : lights_.sphere_lights) {
      // A prop's lamp is absent from the world without props; its light is a change the prop makes.
      if ((with_props || !light.prop_only) && light.intersect(origin, direction, t, light_pdf) && in_front(t)) {
        if (seen(light.visible_to_camera)) add(index, light.radiance_toward(origin) * weight(light_pdf));
        light_in_front = true;
        if (light.prop_only) result.touched_prop = true;
      }
      ++index;
    }
    index = lights_.first_disc();
    for (const DiscLight& light : lights_.disc_lights) {
      if (light.intersect(origin, direction, t, light_pdf) && in_front(t)) {
        if (seen(light.visible_to_camera)) add(index, light.radiance * weight(light_pdf));
        light_in_front = true;
      }
      ++index;
    }
    // Point lights are deltas: no ray meets them.
    if (t_hit < kInfinity) return;
    index = lights_.first_sun();
    for (const SunLight& sun : lights_.suns) {
      const float p = sun.pdf(direction);
      if (p > 0.f && seen(sun.visible_to_camera) && lights_.arrives_from_outside(origin, direction, sun.through_portals))
        add(index, sun.radiance() * weight(p));
      ++index;
    }
    const EnvironmentLight* environment = lights_.environment.get();
    if (environment && seen(environment->visible_to_camera()) &&
        lights_.arrives_from_outside(origin, direction, environment->through_portals())) {
      const float p = sky_through_portals_ ? portals_.pdf(origin, direction) : environment->pdf(direction);
      add(lights_.environment_index(), environment->radiance(direction) * weight(p));
    }
  }

  // Next-event estimation: one sample toward every light of the rig and one
  // toward an emissive triangle, MIS-weighted against the BSDF's density for
  // the same direction. Dielectrics also receive light through the surface
  // (wi.z < 0).
  template <typename Add>
  void direct_light(const SurfacePoint& sp, const Frame& frame, const Eigen::Vector3f& wo, const Bsdf& bsdf,
                    SobolSampler& sampler,
                    bool with_props, PathResult& result, const Add& add) const {
    // `surface_point`: the sampled point of a light that is geometry (an
    // emissive triangle, lifted off it toward the shading point); the shadow
    // ray then ends just before it. Lights that are not geometry end it a
    // fraction short of the sampled distance.
    const auto connect = [&](const LightSample& ls, const Eigen::Vector3f* surface_point = nullptr) -> Eigen::Vector3f {
      if (!(ls.pdf > 0.f) || !std::isfinite(ls.pdf)) return Eigen::Vector3f::Zero();
      const float cos_geometric = ls.direction.dot(sp.geometric_normal);
      const Eigen::Vector3f wi = frame.to_local(ls.direction);
      if (cos_geometric == 0.f || (cos_geometric > 0.f) != (wi.z() > 0.f)) return Eigen::Vector3f::Zero();
      if (wi.z() < 0.f && !bsdf.has_transmission()) return Eigen::Vector3f::Zero();
      const Eigen::Vector3f f = bsdf.eval(wo, wi);
      if (!(f.maxCoeff() > 0.f)) return Eigen::Vector3f::Zero();
      const Eigen::Vector3f origin =
          offset_origin(sp.position, cos_geometric > 0.f ? sp.geometric_normal : Eigen::Vector3f(-sp.geometric_normal));
      Eigen::Vector3f shadow_direction = ls.direction;
      float shadow_length = ls.distance;
      if (surface_point) {
        // From the lifted origin to the lifted light point: a ray along
        // ls.direction from the lifted origin would pass the emitter's
        // surface when the lift exceeds the shortening.
        shadow_direction = *surface_point - origin;
        shadow_length = shadow_direction.norm();
        if (!(shadow_length > 0.f)) return Eigen::Vector3f::Zero();
        shadow_direction /= shadow_length;
      }
      const float distance = std::isinf(shadow_length) ? kInfinity : shadow_length * (1.f - kShadowShortening);
      if (shadowed(origin, shadow_direction, distance, with_props, result)) return Eigen::Vector3f::Zero();
      // A delta light's density is infinite: BSDF sampling never finds it, weight 1.
      const float weight = detail::power_heuristic(ls.delta ? kInfinity : ls.pdf, bsdf.pdf(wo, wi));
      return f.cwiseProduct(ls.radiance) * (std::abs(wi.z()) * weight / ls.pdf);
    };
    // Two numbers per light whether it emits or not: the streams of the
    // with-prop and without-prop paths stay aligned.
    int index = 0;
    for (const detail::AreaLightSampler& light : area_samplers_) {
      const Eigen::Vector2f u = sampler.get2d();
      add(index++, connect(light.sample(sp.position, u.x(), u.y())));
    }
    for (const SphereLight& light : lights_.sphere_lights) {
      const Eigen::Vector2f u = sampler.get2d();
      if (light.prop_only && !with_props) {
        ++index;
        continue;
      }
      const Eigen::Vector3f arriving = connect(light.sample(sp.position, u.x(), u.y()));
      if (light.prop_only && arriving.maxCoeff() > 0.f) result.touched_prop = true;
      add(index++, arriving);
    }
    // Light from outside enters a room only through its windows (portals).
    const auto through_windows = [&](LightSample ls, bool through_portals) {
      if (!lights_.arrives_from_outside(sp.position, ls.direction, through_portals)) ls.pdf = 0.f;
      return ls;
    };
    for (const SunLight& sun : lights_.suns) {
      const Eigen::Vector2f u = sampler.get2d();
      add(index++, connect(through_windows(sun.sample(u.x(), u.y()), sun.through_portals)));
    }
    for (const DiscLight& light : lights_.disc_lights) {
      const Eigen::Vector2f u = sampler.get2d();
      add(index++, connect(light.sample(sp.position, u.x(), u.y())));
    }
    for (const PointLight& light : lights_.point_lights) {
      const Eigen::Vector2f u = sampler.get2d();  // unused: kept for the streams' alignment
      add(index++, connect(light.sample(sp.position, u.x(), u.y())));
    }
    if (lights_.environment) {
      const Eigen::Vector2f u = sampler.get2d();
      LightSample ls;
      if (sky_through_portals_) ls = portals_.sample(sp.position, u.x(), u.y());
      else ls.direction = lights_.environment->sample(u.x(), u.y(), ls.pdf);
      ls.distance = kInfinity;
      ls.radiance = lights_.environment->radiance(ls.direction);
      add(index, connect(through_windows(ls, lights_.environment->through_portals())));
    }
    if (sample_emissive_) {
      // One emissive triangle, picked by what it may deliver here (the light BVH).
      const float u_pick = sampler.get1d();
      const Eigen::Vector2f u = sampler.get2d();
      const detail::EmissiveLights::Pick pick = emissive_.pick(sp.position, sp.shading_normal, u_pick);
      if (pick.index < 0) return;
      const detail::EmissiveTriangle& triangle = emissive_.triangle(pick.index);
      if (triangle.prop && !with_props) return;  // absent from this world
      LightSample ls = emissive_.sample(pick.index, sp.position, u.x(), u.y());
      if (!(ls.pdf > 0.f) || rig_light_before(sp.position, ls.direction, ls.distance, with_props)) return;
      ls.pdf *= pick.pmf;
      const Eigen::Vector3f on_light = sp.position + ls.direction * ls.distance;
      const Eigen::Vector3f lifted =
          offset_origin(on_light, triangle.normal.dot(ls.direction) < 0.f ? triangle.normal : Eigen::Vector3f(-triangle.normal));
      const Eigen::Vector3f arriving = connect(ls, &lifted);
      if (triangle.prop && arriving.maxCoeff() > 0.f) result.touched_prop = true;
      add(emissive_slot(), arriving);
    }
  }

  const Scene& scene_;
  const LightRig& lights_;
  int max_bounces_;
  float max_sample_luminance_;
  bool layers_;
  bool caustics_;
  bool prop_interreflection_;
  std::vector<detail::AreaLightSampler> area_samplers_;  // lights_.area_lights, derived once
  detail::PortalSampler portals_;                        // lights_.portals
  bool sky_through_portals_;  // the environment is sampled through the windows
  const detail::EmissiveLights& emissive_;
  bool sample_emissive_;
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
  if (settings.first_sample < 0) throw std::invalid_argument("render: first_sample must be >= 0");
  if (std::isnan(settings.max_sample_luminance)) throw std::invalid_argument("render: max_sample_luminance is NaN");
}

struct CameraRay {
  Eigen::Vector3f origin, direction;
};

CameraRay jittered_camera_ray(const PinholeCamera& camera, int x, int y, SobolSampler& sampler) {
  const Eigen::Vector2f jitter = sampler.get2d();
  const double u = x + jitter.x() - 0.5, v = y + jitter.y() - 0.5;
  return {camera.center_world.cast<float>(), camera.ray_direction(u, v).cast<float>()};
}

uint64_t pixel_key(const PinholeCamera& camera, int x, int y) {
  return static_cast<uint64_t>(y) * static_cast<uint64_t>(camera.width) + static_cast<uint64_t>(x);
}

// Sample settings.first_sample + s of a pixel of a plain render; the
// differential render draws from its own seed (differential_sample).
SobolSampler image_sampler(const RenderSettings& settings, const PinholeCamera& camera, int x, int y, int s) {
  return SobolSampler(detail::mix_seed(settings.seed, 0), pixel_key(camera, x, y),
                      static_cast<uint32_t>(settings.first_sample) + static_cast<uint32_t>(s));
}

}  // namespace

namespace {

cv::Mat render_world(const Scene& scene, const PinholeCamera& camera, const LightRig& lights,
                     const RenderSettings& settings, RenderStats* stats, bool with_props) {
  check_inputs(scene, camera, settings);
  const auto start = std::chrono::steady_clock::now();
  cv::Mat image(camera.height, camera.width, CV_32FC3, cv::Scalar::all(0));
  const PathIntegrator integrator(scene, lights, settings, /*layers=*/false);
  std::atomic<uint64_t> rays{0};
  for_each_tile(camera.width, camera.height, settings, [&](int x0, int y0, int x1, int y1) {
    uint64_t tile_rays = 0;
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) {
        Eigen::Vector3f sum = Eigen::Vector3f::Zero();
        for (int s = 0; s < settings.samples_per_pixel; ++s) {
          SobolSampler sampler = image_sampler(settings, camera, x, y, s);
          const CameraRay ray = jittered_camera_ray(camera, x, y, sampler);
          const PathResult path = integrator.trace(ray.origin, ray.direction, sampler, with_props);
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

}  // namespace

std::vector<cv::Mat> render_background_light_images(const Scene& scene, const PinholeCamera& camera,
                                                    const LightRig& lights, const RenderSettings& settings,
                                                    RenderStats* stats) {
  check_inputs(scene, camera, settings);
  const auto start = std::chrono::steady_clock::now();
  const int k = lights.count();
  std::vector<cv::Mat> images;
  for (int i = 0; i < k; ++i) images.emplace_back(camera.height, camera.width, CV_32FC3, cv::Scalar::all(0));
  const PathIntegrator integrator(scene, lights, settings, /*layers=*/true);
  std::atomic<uint64_t> rays{0};
  for_each_tile(camera.width, camera.height, settings, [&](int x0, int y0, int x1, int y1) {
    uint64_t tile_rays = 0;
    std::vector<Eigen::Vector3f> sum(k);
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) {
        std::fill(sum.begin(), sum.end(), Eigen::Vector3f::Zero());
        for (int s = 0; s < settings.samples_per_pixel; ++s) {
          SobolSampler sampler = image_sampler(settings, camera, x, y, s);
          const CameraRay ray = jittered_camera_ray(camera, x, y, sampler);
          const PathResult path = integrator.trace(ray.origin, ray.direction, sampler, false);
          for (int i = 0; i < k; ++i) sum[i] += path.per_light[i];
          tile_rays += path.rays;
        }
        for (int i = 0; i < k; ++i) {
          const Eigen::Vector3f v = sum[i] / static_cast<float>(settings.samples_per_pixel);
          images[i].at<cv::Vec3f>(y, x) = cv::Vec3f(v.x(), v.y(), v.z());
        }
      }
    rays += tile_rays;
  });
  if (stats) {
    stats->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    stats->camera_samples = static_cast<uint64_t>(camera.width) * camera.height * settings.samples_per_pixel;
    stats->rays = rays;
  }
  return images;
}

cv::Mat render_image(const Scene& scene, const PinholeCamera& camera, const LightRig& lights,
                     const RenderSettings& settings, RenderStats* stats) {
  return render_world(scene, camera, lights, settings, stats, true);
}

cv::Mat render_background_image(const Scene& scene, const PinholeCamera& camera, const LightRig& lights,
                                const RenderSettings& settings, RenderStats* stats) {
  return render_world(scene, camera, lights, settings, stats, false);
}

PrimaryBuffers render_primary_buffers(const Scene& scene, const PinholeCamera& camera, bool with_props,
                                      const cv::Mat& only_where) {
  if (!only_where.empty() && (only_where.type() != CV_8U || only_where.cols != camera.width || only_where.rows != camera.height))
    throw std::invalid_argument("render_primary_buffers: only_where must be CV_8U at the camera's size");
  PrimaryBuffers out;
  out.depth = cv::Mat(camera.height, camera.width, CV_32F, cv::Scalar(0));
  out.albedo = cv::Mat(camera.height, camera.width, CV_32FC3, cv::Scalar::all(0));
  out.normal = cv::Mat(camera.height, camera.width, CV_32FC3, cv::Scalar::all(0));
  out.prop_coverage = cv::Mat(camera.height, camera.width, CV_8U, cv::Scalar(0));
  const Eigen::Vector3f forward = (camera.R_world_from_cam * Eigen::Vector3d::UnitZ()).cast<float>();
  const Eigen::Vector3f origin = camera.center_world.cast<float>();
  for (int y = 0; y < camera.height; ++y)
    for (int x = 0; x < camera.width; ++x) {
      if (!only_where.empty() && !only_where.at<uint8_t>(y, x)) continue;
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

cv::Mat render_prop_coverage(const Scene& scene, const PinholeCamera& camera, const cv::Rect& region,
                             int rays_per_side, int threads) {
  if (rays_per_side < 1 || rays_per_side > 16)
    throw std::invalid_argument("render_prop_coverage: rays_per_side must be in 1..16");
  const cv::Rect r = region & cv::Rect(0, 0, camera.width, camera.height);
  cv::Mat coverage(r.size(), CV_32F, cv::Scalar(0));
  if (r.empty()) return coverage;
  const Eigen::Vector3f origin = camera.center_world.cast<float>();
  const float per_ray = 1.f / static_cast<float>(rays_per_side * rays_per_side);
  RenderSettings tiling;
  tiling.threads = threads;
  for_each_tile(r.width, r.height, tiling, [&](int x0, int y0, int x1, int y1) {
    for (int row = y0; row < y1; ++row) {
      float* out = coverage.ptr<float>(row);
      for (int x = x0; x < x1; ++x) {
        int hits = 0;
        for (int j = 0; j < rays_per_side; ++j)
          for (int i = 0; i < rays_per_side; ++i) {
            // Pixel centres are at integer coordinates (ray_direction).
            const double u = r.x + x + (i + 0.5) / rays_per_side - 0.5;
            const double v = r.y + row + (j + 0.5) / rays_per_side - 0.5;
            const Eigen::Vector3f dir = camera.ray_direction(u, v).cast<float>();
            RayHit hit;
            hits += scene.intersect(origin, dir, kInfinity, true, hit) && scene.layer(hit.mesh) == Layer::Prop;
          }
        out[x] = static_cast<float>(hits) * per_ray;
      }
    }
  });
  return coverage;
}

namespace {

// The per-sample change of one differential sample (see render_differential).
void differential_sample(const PathIntegrator& integrator, const PinholeCamera& camera, uint64_t seed, int x, int y,
                         int sample, DifferentialPixel& pixel) {
  SobolSampler sampler(detail::mix_seed(seed, 1), pixel_key(camera, x, y), static_cast<uint32_t>(sample));
  const CameraRay ray = jittered_camera_ray(camera, x, y, sampler);
  // Both worlds consume the same random numbers: where the prop does not
  // interfere, the two paths are identical and their difference is exactly 0.
  SobolSampler sampler_without = sampler;
  const PathResult with_prop = integrator.trace(ray.origin, ray.direction, sampler, true);
  pixel.rays += with_prop.rays;
  ++pixel.samples;
  Eigen::Vector3f delta = Eigen::Vector3f::Zero();
  const bool layers = !with_prop.per_light.empty();
  if (layers && pixel.change_sum_per_light.size() != with_prop.per_light.size())
    pixel.change_sum_per_light.assign(with_prop.per_light.size(), Eigen::Vector3f::Zero());
  if (with_prop.prop_primary) {
    ++pixel.prop_samples;
    delta = with_prop.radiance;
    for (size_t i = 0; layers && i < with_prop.per_light.size(); ++i) pixel.change_sum_per_light[i] += with_prop.per_light[i];
  } else if (with_prop.touched_prop) {
    const PathResult without = integrator.trace(ray.origin, ray.direction, sampler_without, false);
    pixel.rays += without.rays;
    ++pixel.second_paths;
    delta = with_prop.radiance - without.radiance;
    const float gain = 0.2126f * delta.x() + 0.7152f * delta.y() + 0.0722f * delta.z();
    const float scale = gain > kMaxBackgroundGainLuminance ? kMaxBackgroundGainLuminance / gain : 1.f;
    delta *= scale;
    for (size_t i = 0; layers && i < with_prop.per_light.size(); ++i)
      pixel.change_sum_per_light[i] += (with_prop.per_light[i] - without.per_light[i]) * scale;
  } else {
    ++pixel.untouched;
    return;
  }
  pixel.change_sum += delta;
  if (sample & 1) pixel.change_sum_odd += delta;
  const double lum = 0.2126 * delta.x() + 0.7152 * delta.y() + 0.0722 * delta.z();
  pixel.change_luminance_sq_sum += lum * lum;
}

}  // namespace

void accumulate_differential_pixels(const Scene& scene, const PinholeCamera& camera, const LightRig& lights,
                                    const RenderSettings& settings, const cv::Rect& rect, int first_sample, int count,
                                    std::vector<DifferentialPixel>& pixels) {
  if (pixels.size() != static_cast<size_t>(rect.area()))
    throw std::invalid_argument("accumulate_differential_pixels: need one pixel per pixel of the rectangle");
  const PathIntegrator integrator(scene, lights, settings, settings.light_layers);
  size_t i = 0;
  for (int y = rect.y; y < rect.br().y; ++y)
    for (int x = rect.x; x < rect.br().x; ++x, ++i)
      for (int s = first_sample; s < first_sample + count; ++s)
        differential_sample(integrator, camera, settings.seed, x, y, s, pixels[i]);
}

DifferentialRender render_differential(const Scene& scene, const PinholeCamera& camera, const LightRig& lights,
                                       const RenderSettings& settings) {
  check_inputs(scene, camera, settings);
  const auto start = std::chrono::steady_clock::now();
  DifferentialRender out;
  out.coverage = cv::Mat(camera.height, camera.width, CV_32F, cv::Scalar(0));
  out.change = cv::Mat(camera.height, camera.width, CV_32FC3, cv::Scalar::all(0));
  const PathIntegrator integrator(scene, lights, settings, settings.light_layers);
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
