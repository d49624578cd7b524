// The photographed scene as render geometry: the depth as a mesh, the
// facades continued out of the frame (outdoors) and the box closing the room
// (indoors). One owner, so the light fit's basis renders and the composite's
// renders see the same world.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "propcam/inference/hidden_facades.h"
#include "propcam/inference/room_enclosure.h"
#include "propcam/render/camera.h"
#include "propcam/render/depth_mesh.h"
#include "propcam/render/scene.h"

namespace propcam::inference {

struct SceneWorldOptions {
  render::DepthMeshOptions depth_mesh;
  HiddenFacadeOptions facades;
  RoomEnclosureOptions enclosure;
};

// Adds the background layer of the scene to `scene` (not committed): the
// depth mesh (albedo per vertex), then the hidden facades' cells, then the
// enclosure's; an empty facade list or box adds nothing. `depth` and
// `albedo` are at the camera's size.
void add_scene_world(render::Scene& scene, const cv::Mat& depth, const cv::Mat& albedo,
                     const render::PinholeCamera& camera, const std::vector<HiddenFacade>& facades,
                     const RoomEnclosure& enclosure, const SceneWorldOptions& options = {});

}  // namespace propcam::inference
