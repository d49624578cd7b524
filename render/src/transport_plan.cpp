#include "propcam/render/transport_plan.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <sstream>

#include "luminance.h"

namespace propcam::render {
namespace {

using Eigen::Vector3f;

constexpr double kPi = std::numbers::pi;
// Roughness below which a metal or glass surface focuses light (caustics).
constexpr float kSpecularMaxRoughness = 0.3f;
// Share of a surface point's hemisphere a prop can fill where it touches the
// floor: the most its bounce light can add, relative to the light already there.
constexpr double kContactHemisphereShare = 0.25;

using detail::luminance;

// The largest share of a spot's light any point of the props' bounding
// sphere gets: its cone's attenuation at the sphere's point nearest the
// axis (1 for a light without a cone, and for props around the light).
double spot_reach(const std::optional<SpotCone>& spot, const Vector3f& light, const Vector3f& centre, float radius) {
  if (!spot) return 1.0;
  const Eigen::Vector3d to = (centre - light).cast<double>();
  const double distance = to.norm();
  if (!(distance > radius)) return 1.0;
  const Eigen::Vector3d axis = spot->direction.cast<double>().normalized();
  const double to_centre = std::acos(std::clamp(axis.dot(to) / distance, -1.0, 1.0));
  const double nearest = std::max(0.0, to_centre - std::asin(radius / distance));
  return spot->attenuation_at_cos(std::cos(nearest));
}

std::string percent(double v) {
  std::ostringstream out;
  out.precision(v < 0.1 ? 2 : 3);
  out << 100.0 * v << "%";
  return out.str();
}

// What the props are made of, where they are, how big.
struct PropSummary {
  Eigen::AlignedBox3f bounds;
  bool glossy = false, specular = false;
  float max_reflectance = 0.f;
  std::vector<std::string> glossy_names;
};

PropSummary summarise_props(const Scene& scene) {
  PropSummary props;
  for (int i = 0; i < scene.mesh_count(); ++i) {
    if (scene.layer(i) != Layer::Prop) continue;
    props.bounds.extend(scene.world_bounds(i));
    for (const Material& m : scene.mesh(i).materials) {
      const bool is_glossy = m.type == Material::Type::Plastic || m.type == Material::Type::Metal ||
                             m.type == Material::Type::Dielectric;
      if (is_glossy) {
        props.glossy = true;
        props.glossy_names.push_back(m.name.empty() ? to_string(m.type) : m.name);
      }
      if ((m.type == Material::Type::Metal || m.type == Material::Type::Dielectric) && m.roughness < kSpecularMaxRoughness)
        props.specular = true;
      const float reflectance = m.type == Material::Type::Dielectric ? 1.f : m.albedo.maxCoeff();
      props.max_reflectance = std::max(props.max_reflectance, m.type == Material::Type::Emissive ? 1.f : reflectance);
    }
  }
  return props;
}

// Irradiance each light gives the props (upper bounds, facing the light) and
// the solid angle it subtends there, in the rig's order.
struct LightAtProps {
  std::vector<double> irradiance, solid_angle;
};

LightAtProps light_at_props(const LightRig& lights, const Vector3f& centre, float radius) {
  const int n = lights.count();
  LightAtProps at{std::vector<double>(n, 0.0), std::vector<double>(n, 0.0)};
  std::vector<double>& irradiance = at.irradiance;
  std::vector<double>& solid_angle = at.solid_angle;
  int index = 0;
  for (const AreaLight& l : lights.area_lights) {
    const double d2 = std::max<double>((l.centre() - centre).squaredNorm(), radius * radius + 1e-6);
    solid_angle[index] = std::min(2 * kPi, l.area() / d2);
    irradiance[index] = luminance(l.radiance) * solid_angle[index];
    ++index;
  }
  for (const SphereLight& l : lights.sphere_lights) {
    const double d2 = std::max<double>((l.center - centre).squaredNorm(), radius * radius + 1e-6);
    solid_angle[index] = std::min(2 * kPi, kPi * l.radius * l.radius / d2);
    irradiance[index] = luminance(l.radiance) * solid_angle[index] * spot_reach(l.spot, l.center, centre, radius);
    ++index;
  }
  for (const SunLight& s : lights.suns) {
    solid_angle[index] = kPi * std::pow(std::sin(s.angular_radius), 2);
    irradiance[index] = s.emits() ? luminance(s.irradiance) : 0.0;
    ++index;
  }
  for (const DiscLight& l : lights.disc_lights) {
    const double d2 = std::max<double>((l.centre - centre).squaredNorm(), radius * radius + 1e-6);
    solid_angle[index] = std::min(2 * kPi, l.area() / d2);
    irradiance[index] = l.emits() ? luminance(l.radiance) * solid_angle[index] : 0.0;
    ++index;
  }
  for (const PointLight& l : lights.point_lights) {
    // A point subtends nothing: the smallest light there is (sharp caustics).
    const double d2 = std::max<double>((l.position - centre).squaredNorm(), radius * radius + 1e-6);
    solid_angle[index] = 0.0;
    irradiance[index] = l.emits() ? luminance(l.intensity) / d2 * spot_reach(l.spot, l.position, centre, radius) : 0.0;
    ++index;
  }
  if (lights.environment) {
    const cv::Scalar mean = cv::mean(lights.environment->image());
    const Vector3f scale = lights.environment->scale();
    solid_angle[index] = 4 * kPi;
    irradiance[index] = kPi * (0.2126 * mean[0] * scale.x() + 0.7152 * mean[1] * scale.y() + 0.0722 * mean[2] * scale.z());
  }
  return at;
}

// Each light's share of the irradiance at the props.
std::vector<double> light_shares(const std::vector<double>& irradiance) {
  double total = 0;
  for (double e : irradiance) total += std::max(0.0, e);
  std::vector<double> share(irradiance.size(), 0.0);
  for (size_t i = 0; i < irradiance.size(); ++i) share[i] = total > 0 ? std::max(0.0, irradiance[i]) / total : 0.0;
  return share;
}

// Lights: keep those that matter at the props.
void prune_lights(const LightRig& lights, const PlanOptions& options, bool have_props, TransportPlan& plan) {
  int index = 0;
  auto keep = [&](int i) {
    const bool kept = !options.allow_skips || !options.prune_lights || !have_props ||
                      plan.light_share[i] >= options.min_light_share;
    if (kept) plan.source_index.push_back(i);
    else
      plan.decisions.push_back({"light " + std::to_string(i), false,
                                "gives " + percent(plan.light_share[i]) + " of the light at the prop (below " +
                                    percent(options.min_light_share) + "): pruned"});
    return kept;
  };
  for (const AreaLight& l : lights.area_lights)
    if (keep(index++)) plan.lights.area_lights.push_back(l);
  for (const SphereLight& l : lights.sphere_lights)
    if (keep(index++)) plan.lights.sphere_lights.push_back(l);
  for (const SunLight& s : lights.suns)
    if (keep(index++)) plan.lights.suns.push_back(s);
  for (const DiscLight& l : lights.disc_lights)
    if (keep(index++)) plan.lights.disc_lights.push_back(l);
  for (const PointLight& l : lights.point_lights)
    if (keep(index++)) plan.lights.point_lights.push_back(l);
  if (lights.environment && keep(index++)) plan.lights.environment = lights.environment;
  plan.lights.portals = lights.portals;
}

// Glossy paths: only materials that need them have them; say which.
void decide_glossy(const PropSummary& props, TransportPlan& plan) {
  if (props.glossy) {
    std::string names;
    for (size_t i = 0; i < props.glossy_names.size() && i < 3; ++i) names += (i ? ", " : "") + props.glossy_names[i];
    plan.decisions.push_back({"glossy", true, "the prop has glossy materials (" + names + ")"});
  } else {
    plan.decisions.push_back({"glossy", false, "every prop material is diffuse: no glossy lobe to sample"});
  }
}

// Caustics: a specular prop under a small strong light.
void decide_caustics(const PropSummary& props, const std::vector<double>& solid_angle, const PlanOptions& options,
                     TransportPlan& plan) {
  int focusing_light = -1;
  for (size_t i = 0; i < solid_angle.size(); ++i)
    if (solid_angle[i] < options.small_light_solid_angle_sr && plan.light_share[i] >= options.strong_light_share)
      focusing_light = static_cast<int>(i);
  if (!options.allow_skips || !options.skip_caustics) {
    plan.decisions.push_back({"caustics", plan.settings.caustics, "not planned (as set)"});
  } else if (!props.specular) {
    plan.settings.caustics = false;
    plan.decisions.push_back({"caustics", false, "no smooth metal or glass on the prop"});
  } else if (focusing_light < 0) {
    plan.settings.caustics = false;
    plan.decisions.push_back({"caustics", false, "smooth metal/glass, but no small light gives >= " +
                                                     percent(options.strong_light_share) + " of the light at the prop"});
  } else {
    plan.decisions.push_back({"caustics", true, "smooth metal/glass under light " + std::to_string(focusing_light) +
                                                    " (" + percent(plan.light_share[focusing_light]) + " of the light)"});
  }
}

// The prop's bounce light onto the photo: at most reflectance x the share
// of the hemisphere it fills at its base.
void decide_interreflection(const PropSummary& props, const PlanOptions& options, TransportPlan& plan) {
  const double bounce = props.max_reflectance * kContactHemisphereShare;
  if (!options.allow_skips || !options.skip_interreflection) {
    plan.decisions.push_back({"prop_interreflection", plan.settings.prop_interreflection, "not planned (as set)"});
  } else if (!props.bounds.isEmpty() && bounce < options.min_visible_change) {
    plan.settings.prop_interreflection = false;
    plan.decisions.push_back({"prop_interreflection", false,
                              "the prop reflects at most " + percent(props.max_reflectance) +
                                  ": its bounce light changes the floor by < " + percent(options.min_visible_change)});
  } else {
    plan.decisions.push_back({"prop_interreflection", true,
                              "the prop's bounce light can change nearby surfaces by up to " + percent(bounce)});
  }
}

}  // namespace

TransportPlan plan_transport(const Scene& scene, const LightRig& lights, const RenderSettings& base,
                             const PlanOptions& options) {
  TransportPlan plan;
  plan.settings = base;
  plan.original_light_count = lights.count();
  const PropSummary props = summarise_props(scene);
  const bool have_props = !props.bounds.isEmpty();
  const Vector3f centre = have_props ? Vector3f(props.bounds.center()) : Vector3f(Vector3f::Zero());
  const float radius = have_props ? 0.5f * props.bounds.sizes().norm() : 0.f;
  const LightAtProps at_props = light_at_props(lights, centre, radius);
  plan.light_share = light_shares(at_props.irradiance);
  prune_lights(lights, options, have_props, plan);
  decide_glossy(props, plan);
  decide_caustics(props, at_props.solid_angle, options, plan);
  decide_interreflection(props, options, plan);
  return plan;
}

LightLayers layers_in_original_order(const TransportPlan& plan, const LightLayers& planned) {
  LightLayers out;
  out.coverage = planned.coverage;
  if (planned.change.empty()) return out;
  const cv::Mat zero(planned.coverage.size(), CV_32FC3, cv::Scalar::all(0));
  out.change.assign(static_cast<size_t>(plan.original_light_count) + 1, zero);
  for (size_t j = 0; j < plan.source_index.size() && j < planned.change.size(); ++j)
    out.change[plan.source_index[j]] = planned.change[j];
  out.change.back() = planned.change.back();  // emissive surfaces
  return out;
}

}  // namespace propcam::render
