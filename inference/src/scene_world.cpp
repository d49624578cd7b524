#include "propcam/inference/scene_world.h"

namespace propcam::inference {

void add_scene_world(render::Scene& scene, const cv::Mat& depth, const cv::Mat& albedo,
                     const render::PinholeCamera& camera, const std::vector<HiddenFacade>& facades,
                     const RoomEnclosure& enclosure, const SceneWorldOptions& options) {
  scene.add_mesh(render::mesh_from_depth(depth, albedo, camera, options.depth_mesh), render::Layer::Background);
  if (!facades.empty()) {
    render::Mesh hidden = hidden_facade_mesh(facades, depth, camera, options.facades);
    if (!hidden.empty()) scene.add_mesh(hidden, render::Layer::Background);
  }
  if (!enclosure.empty()) {
    render::Mesh box = room_enclosure_mesh(enclosure, depth, camera, options.enclosure);
    if (!box.empty()) scene.add_mesh(box, render::Layer::Background);
  }
}

}  // namespace propcam::inference
