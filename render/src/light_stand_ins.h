// Which emissive triangles a light of the rig stands for (internal to
// render/): a synthetic room's ceiling panel has an area light just below
// it, a lamp prop's globe a sphere light around it (props.h prop_lights).
// The path tracer counts such a surface through the light only; when every
// emissive triangle is stood for it does not sample them at all.
#pragma once

#include "emissive_lights.h"
#include "propcam/render/lights.h"

namespace propcam::render::detail {

// An emissive triangle no further than this (m) behind an area or disc
// light's emitting side, within its outline, is stood for by the light.
constexpr float kStandInDepth = 0.01f;

// True when every emissive triangle lies inside a sphere light, or within
// kStandInDepth behind an area or disc light's outline. Mesh by mesh first
// (a sphere around its triangles, the corners of its box), then triangle by
// triangle for the meshes that test leaves open.
bool rig_stands_for_every_emitter(const LightRig& rig, const EmissiveLights& emitters);

}  // namespace propcam::render::detail
