#include "worlds/synthetic_truth.h"

#include "propcam/render/depth_mesh.h"
#include "propcam/render/scene.h"

namespace propcam::firmware {

namespace {

// Renders the photo of `shot.room` and fills the truth every generator
// shares: the exact camera, depth, albedo, normals and the floor plane.
// Pixels that see nothing are sky (kSkyDepthM, facing the camera).
void render_shot(SyntheticShot& shot, const render::RenderSettings& settings, bool indoor, const std::string& why) {
  render::Scene scene;
  scene.add_mesh(shot.room.room, render::Layer::Background);
  scene.commit();
  const render::PinholeCamera& cam = shot.room.camera;
  shot.photo_linear = render::render_image(scene, cam, shot.room.lights, settings, &shot.photo_stats);
  const render::PrimaryBuffers gt = render::render_primary_buffers(scene, cam, false);
  inference::SceneModel& t = shot.truth;
  t.width = cam.width;
  t.height = cam.height;
  t.fx = cam.fx;
  t.fy = cam.fy;
  t.cx = cam.cx;
  t.cy = cam.cy;
  t.R_world_from_cam = cam.R_world_from_cam;
  t.camera_height_m = cam.center_world.y();
  t.depth = gt.depth.clone();
  t.albedo = gt.albedo;
  t.normals = gt.normal.clone();
  t.indoor = indoor;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x)
      if (!indoor && !(t.depth.at<float>(y, x) > 0)) {
        t.depth.at<float>(y, x) = static_cast<float>(render::kSkyDepthM);
        const Eigen::Vector3d d = -cam.ray_direction(x, y);
        t.normals.at<cv::Vec3f>(y, x) = cv::Vec3f(static_cast<float>(d.x()), static_cast<float>(d.y()), static_cast<float>(d.z()));
      }
  t.planes.push_back({"floor", Eigen::Vector3d::UnitY(), 0.0});
  inference::StageReport r;
  r.stage = "ground_truth";
  r.why = why;
  t.reports.push_back(r);
}

}  // namespace

SyntheticShot shoot_synthetic_room(const render::SyntheticRoomSpec& spec, const render::RenderSettings& settings) {
  SyntheticShot shot;
  shot.room = render::make_synthetic_room(spec);
  render_shot(shot, settings, true, "synthetic room seed " + std::to_string(spec.seed));
  // Scene models put the world origin on the floor below the camera.
  const render::PinholeCamera& cam = shot.room.camera;
  const Eigen::Vector3d shift(cam.center_world.x(), 0.0, cam.center_world.z());
  for (const auto& a : shot.room.lights.area_lights) {
    inference::LightSource l;
    l.type = inference::LightSource::Type::Area;
    l.corner = a.corner.cast<double>() - shift;
    l.edge_u = a.edge_u.cast<double>();
    l.edge_v = a.edge_v.cast<double>();
    l.position = a.centre().cast<double>() - shift;
    l.intensity = a.radiance.cast<double>();
    shot.truth.lights.push_back(l);
  }
  return shot;
}

SyntheticShot shoot_synthetic_street(const render::SyntheticStreetSpec& spec, const render::RenderSettings& settings) {
  const render::SyntheticStreet street = render::make_synthetic_street(spec);
  SyntheticShot shot;
  shot.room.camera = street.camera;
  shot.room.room = street.scene;
  shot.room.lights = street.lights;
  shot.room.room_min = street.scene_min;
  shot.room.room_max = street.scene_max;
  shot.room.free_floor_point = street.free_ground_point;
  render_shot(shot, settings, false, "synthetic street seed " + std::to_string(spec.seed));
  for (const auto& sun : street.lights.suns) {
    inference::LightSource l;
    l.type = inference::LightSource::Type::Sun;
    l.direction = sun.direction.cast<double>().normalized();
    l.intensity = sun.irradiance.cast<double>();
    shot.truth.lights.push_back(l);
  }
  // The sky: a light of the scene like the sun (a truth folder without it
  // renders the street lit by the sun alone).
  if (street.lights.environment && street.lights.environment->valid()) {
    inference::LightSource sky;
    sky.type = inference::LightSource::Type::Ibl;
    sky.environment = street.lights.environment->image().clone();
    sky.intensity = street.lights.environment->scale().cast<double>();
    shot.truth.lights.push_back(sky);
  }
  return shot;
}

Eigen::Vector2d free_floor_pixel(const render::SyntheticRoom& room) {
  Eigen::Vector2d px;
  room.camera.project(room.free_floor_point.cast<double>(), px);
  return px;
}

cv::Mat render_full_insertion(const render::SyntheticRoom& room, const render::Mesh& prop,
                              const render::PropPlacement& placement, const render::RenderSettings& settings) {
  render::Scene support;
  support.add_mesh(room.room, render::Layer::Background);
  support.commit();
  const render::PlacedProp placed = render::place_prop(prop, room.camera, support, placement);
  render::Scene scene;
  scene.add_mesh(room.room, render::Layer::Background);
  render::Mesh mesh = prop;
  mesh.transform(placed.world_from_prop);
  scene.add_mesh(std::move(mesh), render::Layer::Prop);
  scene.commit();
  return render::render_image(scene, room.camera, room.lights, settings);
}

}  // namespace propcam::firmware
