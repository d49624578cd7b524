// Procedurally generated preset props, so the appliance can composite
// something without any asset files.
//
// Every prop is built at natural size in metres, standing on the ground:
// bounding box min y == 0 and centred on x = 0, z = 0; +y is up and +z is the
// prop's front (a chair's backrest is at -z, a mug's handle points to +x).
// Surfaces are closed with outward counter-clockwise winding and per-vertex
// normals (split at hard edges); every triangle has a named material.
#pragma once

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "propcam/render/lights.h"
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

// The light a prop's emissive surfaces cast, for next-event estimation (the
// path tracer finds emissive triangles only by BSDF sampling): one sphere
// light per emissive material, centred on its triangles' area centroid in
// world space, just enclosing them (so they never shadow their own light),
// with the material's radiance scaled to keep its power (one-sided surface of
// area A: L*pi*A). The lights are prop_only: absent from the world without
// props. Empty when the prop has no emissive triangles.
std::vector<SphereLight> prop_lights(const Mesh& prop, const Eigen::Affine3f& world_from_prop);

// The preset rendered by the path tracer: on a large 50% grey diffuse ground
// under a key area light and a dim uniform sky, camera from the front right
// and above, framing the bounding sphere. Square, CV_32FC3 linear RGB (the
// prop's own lights included). Throws std::invalid_argument as make_prop.
cv::Mat render_prop_thumbnail(const std::string& name, int size = 256, int samples_per_pixel = 64);
// The same for any mesh (a prop from a USB stick): the ground under its
// lowest point. Throws std::invalid_argument for an empty mesh.
cv::Mat render_mesh_thumbnail(const Mesh& prop, int size = 256, int samples_per_pixel = 64);

}  // namespace propcam::render
