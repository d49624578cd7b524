// Turns a depth map seen by a pinhole camera into a textured triangle mesh:
// the photo's surfaces as geometry for shadows, occlusion and interreflection.
#pragma once

#include <opencv2/core.hpp>

#include "propcam/render/camera.h"
#include "propcam/render/mesh.h"

namespace propcam::render {

// Depth at or beyond this marks sky (or anything with no surface): no mesh there.
constexpr float kSkyDepthM = 1.0e4f;

struct DepthMeshOptions {
  int step_pixels = 2;  // grid spacing of the vertices
  // Triangles whose vertex depths differ by more than this ratio span a depth
  // discontinuity and are dropped, so no "rubber sheet" joins fore- and background.
  float max_depth_ratio = 1.15f;
};

// `depth` is CV_32F metres along camera z (<= 0, non-finite or >= kSkyDepthM marks no surface);
// `albedo` is CV_32FC3 linear RGB of the same size, used as the mesh texture.
Mesh mesh_from_depth(const cv::Mat& depth, const cv::Mat& albedo, const PinholeCamera& camera,
                     const DepthMeshOptions& options = {});

}  // namespace propcam::render
