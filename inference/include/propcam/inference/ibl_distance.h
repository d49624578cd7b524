// A rendering-based distance between two environment maps (the margin of the
// paper's IBL ranking): a diffuse sphere rendered under each, compared after
// normalising exposure. Diffuse shading only needs the first nine spherical-
// harmonic coefficients of the radiance (Ramamoorthi & Hanrahan 2001), so the
// "render" is exact for a Lambertian sphere and costs one pass over the map.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace propcam::inference {

// 9 real SH coefficients (bands 0-2) per RGB channel of a latlong (EnvironmentLight
// convention). Negative and non-finite texels count as 0.
using ShRadiance = Eigen::Matrix<double, 9, 3>;
ShRadiance project_radiance_sh(const cv::Mat& latlong);

// Irradiance on a surface with unit normal n (RGB, W/m^2 for radiance in W/sr/m^2).
Eigen::Vector3d sh_irradiance(const ShRadiance& sh, const Eigen::Vector3d& normal);

// RMS difference of the two diffuse spheres' radiosity over all normals
// (solid-angle weighted, RGB), each scaled to mean luminance 1 first (a photo
// does not fix exposure). 0 for identical lighting up to scale; a black map
// counts as uniform grey lighting's opposite: its normalised sphere is 0.
double ibl_render_distance(const ShRadiance& a, const ShRadiance& b);
// The same with each map turned: the sphere's normal n is lit by map a from
// rotation_a * n and by map b from rotation_b * n (e.g. each map seen from the
// heading of a view cut from it, ibl_ranking.h). Throws std::invalid_argument
// for a non-finite rotation.
double ibl_render_distance(const ShRadiance& a, const Eigen::Matrix3d& rotation_a, const ShRadiance& b,
                           const Eigen::Matrix3d& rotation_b);

}  // namespace propcam::inference
