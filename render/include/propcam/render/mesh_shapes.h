// Building blocks of generated scenes: quads and axis-aligned boxes with uvs.
#pragma once

#include <Eigen/Core>

#include "propcam/render/mesh.h"

namespace propcam::render {

// Adds the quad a-b-c-d (counter-clockwise seen from the side it faces) with
// uvs in metres divided by `metres_per_tile`.
void add_quad(Mesh& mesh, const Eigen::Vector3f& a, const Eigen::Vector3f& b, const Eigen::Vector3f& c,
              const Eigen::Vector3f& d, int material, float metres_per_tile);

// Axis-aligned box with outward faces (no bottom face).
void add_box(Mesh& mesh, const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, int material);

}  // namespace propcam::render
