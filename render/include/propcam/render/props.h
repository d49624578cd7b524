// Procedurally generated preset props, so the appliance can composite
// something without any asset files.
//
// Every prop is built at natural size in metres, standing on the ground:
// bounding box min y == 0 and centred on x = 0, z = 0; +y is up and +z is the
// prop's front (a chair's backrest is at -z, a mug's handle points to +x).
// Surfaces are closed with outward counter-clockwise winding and per-vertex
// normals (split at hard edges); every triangle has a named material.
#pragma once

#include <string>
#include <vector>

#include "propcam/render/mesh.h"

namespace propcam::render {

struct PropPreset {
  std::string name;         // key for make_prop
  std::string description;  // one line for menus
  float natural_height_m;   // bounding box height of make_prop(name)
};

// All presets, always in the same order (menus index into it).
const std::vector<PropPreset>& prop_presets();

// Builds the named preset; throws std::invalid_argument listing the valid names.
Mesh make_prop(const std::string& name);

}  // namespace propcam::render
