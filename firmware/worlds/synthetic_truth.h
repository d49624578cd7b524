// Synthetic rooms as the rest of PropCam sees them: a photo, its exact scene
// model (ground truth), and a full render with a prop inserted.
#pragma once

#include <opencv2/core.hpp>
#include <string>

#include "propcam/inference/scene_model.h"
#include "propcam/render/path_tracer.h"
#include "propcam/render/placement.h"
#include "propcam/render/synthetic_room.h"
#include "propcam/render/synthetic_street.h"

namespace propcam::firmware {

struct SyntheticShot {
  render::SyntheticRoom room;
  cv::Mat photo_linear;            // CV_32FC3
  inference::SceneModel truth;     // exact camera, depth, albedo, area lights
  render::RenderStats photo_stats;
};

SyntheticShot shoot_synthetic_room(const render::SyntheticRoomSpec& spec, const render::RenderSettings& settings);

// A street the same way: `room` holds the street (its mesh, camera, sun and
// sky, free ground point); sky pixels of the truth have depth kSkyDepthM.
SyntheticShot shoot_synthetic_street(const render::SyntheticStreetSpec& spec, const render::RenderSettings& settings);

// Pixel where the room's free floor point is seen (for --at).
Eigen::Vector2d free_floor_pixel(const render::SyntheticRoom& room);

// The same room rendered with the prop really in it (the reference a
// composite should approach). `placement` uses the same rules as composite.
cv::Mat render_full_insertion(const render::SyntheticRoom& room, const render::Mesh& prop,
                              const render::PropPlacement& placement, const render::RenderSettings& settings);

}  // namespace propcam::firmware
