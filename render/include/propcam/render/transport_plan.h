// Simulate only what the scene calls for: before rendering, decide which
// light transport the prop's effect needs (glossy paths, caustics, the
// prop's bounce light, each light's shadows) and say why. The renderer then
// skips the rest; `propcam composite --explain` prints the decisions and
// `propcam bench` measures what each skip saves and costs.
#pragma once

#include <string>
#include <vector>

#include "propcam/render/lights.h"
#include "propcam/render/path_tracer.h"
#include "propcam/render/relight.h"
#include "propcam/render/scene.h"

namespace propcam::render {

struct PlanOptions {
  // A change smaller than this (relative to the light already there) is below
  // what an 8-bit display shows at interactive noise levels.
  double min_visible_change = 0.02;
  // Lights giving less than this share of the irradiance at the prop are pruned.
  double min_light_share = 0.01;
  // Caustics need a small strong light: one that subtends less than this
  // solid angle at the prop (steradians)...
  double small_light_solid_angle_sr = 0.05;
  // ...and gives at least this share of the prop's irradiance.
  double strong_light_share = 0.1;
  bool allow_skips = true;  // false: simulate everything (the reference)
  // Each kind of skip on its own (for measuring them one by one).
  bool prune_lights = true;
  bool skip_caustics = true;
  bool skip_interreflection = true;
};

struct TransportDecision {
  std::string effect;  // "glossy", "caustics", "prop_interreflection", "light N"
  bool simulated = true;
  std::string why;
};

struct TransportPlan {
  RenderSettings settings;       // the base settings with the transport switches decided
  LightRig lights;               // without the pruned lights
  std::vector<int> source_index; // planned light j -> index in the original rig
  int original_light_count = 0;
  std::vector<double> light_share;  // per original light: share of the irradiance at the props
  std::vector<TransportDecision> decisions;
};

// Looks at the props of `scene` (materials, size, position) and at the lights.
TransportPlan plan_transport(const Scene& scene, const LightRig& lights, const RenderSettings& base,
                             const PlanOptions& options = {});

// Light layers of a planned render, back in the original rig's order (pruned
// lights get empty, zero layers; the emissive slot stays last).
LightLayers layers_in_original_order(const TransportPlan& plan, const LightLayers& planned);

}  // namespace propcam::render
