#include "propcam/inference/scene_model.h"

#include <filesystem>
#include <fstream>
#include <limits>
#include <stdexcept>

#include "propcam/capture/image_file.h"
#include "propcam/inference/physical_ranges.h"

namespace propcam::inference {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// A point light is rendered as a sphere this small (m): a bulb.

json vec(const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }

Eigen::Vector3d vec3(const json& j, const char* what) {
  if (!j.is_array() || j.size() != 3) throw std::runtime_error(std::string("scene.json: ") + what + " is not [x,y,z]");
  return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()};
}

// An int field. nlohmann converts a float (1e300) to int with a plain cast,
// which is undefined out of range, so only integers that fit are accepted.
int json_int(const json& j, const char* what) {
  constexpr auto kMin = std::numeric_limits<int>::min();
  constexpr auto kMax = std::numeric_limits<int>::max();
  bool fits = false;
  if (j.is_number_unsigned()) fits = j.get<std::uint64_t>() <= static_cast<std::uint64_t>(kMax);
  else if (j.is_number_integer()) fits = j.get<std::int64_t>() >= kMin && j.get<std::int64_t>() <= kMax;
  if (!fits) throw std::runtime_error(std::string("scene.json: ") + what + " is not an integer in int's range");
  return j.get<int>();
}

int json_int_or(const json& object, const char* key, int fallback) {
  return object.contains(key) ? json_int(object.at(key), key) : fallback;
}

// A file the scene names must lie inside its folder (lights/ibl_0.exr).
fs::path file_inside(const fs::path& dir, const std::string& name) {
  const fs::path relative(name);
  bool escapes = name.empty() || relative.is_absolute();
  for (const auto& part : relative)
    if (part == "..") escapes = true;
  if (escapes) throw std::runtime_error("scene.json: file '" + name + "' is not inside the scene folder");
  return dir / relative;
}

LightSource::Type light_type_from_string(const std::string& s) {
  if (s == "area") return LightSource::Type::Area;
  if (s == "point") return LightSource::Type::Point;
  if (s == "sun") return LightSource::Type::Sun;
  if (s == "ibl") return LightSource::Type::Ibl;
  throw std::runtime_error("scene.json: unknown light type '" + s + "'");
}

// Bounds on the imaging a scene file may carry: an edge blur and a noise
// level beyond these are not a camera's (the estimators stop at 8 px).
constexpr double kMaxImagingBlurPx = 8.0, kMaxImagingNoise = 0.5;
// A surface 1 mm away; a circle of confusion growing 1e4 px per dioptre.
constexpr double kMaxDefocusDioptres = 1000.0, kMaxDefocusPxPerDioptre = 1.0e4;

json defocus_json(const render::Defocus& d) {
  json bands = json::array();
  for (const render::DepthBandBlur& b : d.bands)
    bands.push_back({{"dioptres", b.dioptres}, {"sigma_px", b.sigma_px}, {"edges", b.edges}});
  return {{"found", d.found}, {"base_sigma_px", d.base_sigma_px}, {"focus_dioptres", d.focus_dioptres},
          {"sigma_px_per_dioptre", d.sigma_px_per_dioptre}, {"min_dioptres", d.min_dioptres},
          {"max_dioptres", d.max_dioptres}, {"bands", bands}};
}

render::Defocus defocus_from_json(const json& j) {
  render::Defocus d;
  d.found = j.value("found", false);
  d.base_sigma_px = j.value("base_sigma_px", 0.0);
  d.focus_dioptres = j.value("focus_dioptres", 0.0);
  d.sigma_px_per_dioptre = j.value("sigma_px_per_dioptre", 0.0);
  d.min_dioptres = j.value("min_dioptres", 0.0);
  d.max_dioptres = j.value("max_dioptres", 0.0);
  for (const json& b : j.value("bands", json::array()))
    d.bands.push_back({b.value("dioptres", 0.0), b.value("sigma_px", 0.0), json_int_or(b, "edges", 0)});
  return d;
}

json imaging_json(const render::PhotoImaging& m) {
  json sigma = json::array();
  for (const auto& bin : m.noise.sigma) sigma.push_back({bin[0], bin[1], bin[2]});
  return {{"blur_measured", m.blur_measured}, {"blur_sigma_px", m.blur_sigma_px}, {"blur_edges", m.blur_edges},
          {"blur_read_through_noise", m.blur_read_through_noise}, {"defocus", defocus_json(m.defocus)},
          {"noise_measured", m.noise_measured}, {"noise_blocks", m.noise_blocks}, {"noise_sigma", sigma}};
}

render::PhotoImaging imaging_from_json(const json& j) {
  render::PhotoImaging m;
  m.blur_measured = j.value("blur_measured", false);
  m.blur_sigma_px = j.value("blur_sigma_px", 0.0);
  m.blur_edges = json_int_or(j, "blur_edges", 0);
  m.blur_read_through_noise = j.value("blur_read_through_noise", false);
  if (j.contains("defocus")) m.defocus = defocus_from_json(j.at("defocus"));
  m.noise_measured = j.value("noise_measured", false);
  m.noise_blocks = json_int_or(j, "noise_blocks", 0);
  const json sigma = j.value("noise_sigma", json::array());
  if (!sigma.empty() && sigma.size() != render::kNoiseBins)
    throw std::runtime_error("scene.json: imaging noise_sigma needs " + std::to_string(render::kNoiseBins) + " bins");
  for (size_t b = 0; b < sigma.size(); ++b) {
    const Eigen::Vector3d v = vec3(sigma[b], "imaging noise_sigma bin");
    for (int c = 0; c < 3; ++c) m.noise.sigma[b][c] = static_cast<float>(v[c]);
  }
  return m;
}

void check_finite(const cv::Mat& m, const char* what) {
  if (!m.empty() && !cv::checkRange(m)) throw std::runtime_error(std::string("scene model: non-finite ") + what);
}

// A window as the renderer's portal (the rig's, and what validate() checks).
render::Portal as_portal(const Window& w) {
  return {w.corner.cast<float>(), w.edge_u.cast<float>(), w.edge_v.cast<float>()};
}

}  // namespace

const char* to_string(LightSource::Type type) {
  switch (type) {
    case LightSource::Type::Area: return "area";
    case LightSource::Type::Point: return "point";
    case LightSource::Type::Sun: return "sun";
    case LightSource::Type::Ibl: return "ibl";
  }
  return "area";
}

std::optional<Eigen::Vector3d> distant_light_direction(const LightSource& light, const Eigen::Vector3d& from) {
  if (light.type == LightSource::Type::Sun)
    return light.direction.allFinite() && light.direction.norm() > 0 ? std::optional(light.direction.normalized())
                                                                       : std::nullopt;
  if (light.type != LightSource::Type::Area) return std::nullopt;
  const Eigen::Vector3d to = light.position - from;
  if (!to.allFinite() || !(to.norm() > kDistantLightM)) return std::nullopt;
  return to.normalized();
}

std::optional<Eigen::Vector3d> distant_light_irradiance(const LightSource& light, const Eigen::Vector3d& from) {
  if (!distant_light_direction(light, from)) return std::nullopt;
  if (light.type == LightSource::Type::Sun) return light.intensity;
  return Eigen::Vector3d(light.intensity * (light.edge_u.cross(light.edge_v).norm() / (light.position - from).squaredNorm()));
}

json to_json(const StageReport& r) {
  json j = {{"stage", r.stage}, {"usable", r.usable}, {"why", r.why}, {"iterations", r.iterations},
            {"seconds", r.seconds}};
  if (r.error >= 0) j["error"] = r.error;
  if (!r.details.empty()) j["details"] = r.details;
  return j;
}

render::PinholeCamera SceneModel::camera() const {
  render::PinholeCamera cam;
  cam.width = width;
  cam.height = height;
  cam.fx = fx;
  cam.fy = fy;
  cam.cx = cx;
  cam.cy = cy;
  cam.R_world_from_cam = R_world_from_cam;
  cam.center_world = {0.0, camera_height_m, 0.0};
  return cam;
}

render::LightRig make_light_rig(const std::vector<LightSource>& lights, bool unit_intensity,
                                const std::vector<Window>& windows) {
  render::LightRig rig;
  for (const Window& w : windows) rig.portals.push_back(as_portal(w));
  for (const LightSource& l : lights) {
    const Eigen::Vector3f intensity = unit_intensity ? Eigen::Vector3f::Ones() : Eigen::Vector3f(l.intensity.cast<float>());
    if (l.type == LightSource::Type::Area) {
      render::AreaLight a;
      a.corner = l.corner.cast<float>();
      a.edge_u = l.edge_u.cast<float>();
      a.edge_v = l.edge_v.cast<float>();
      a.radiance = intensity;
      rig.area_lights.push_back(a);
    } else if (l.type == LightSource::Type::Sun) {
      render::SunLight sun;
      sun.direction = l.direction.cast<float>();
      sun.irradiance = intensity;
      sun.through_portals = l.through_windows;
      rig.suns.push_back(sun);
    } else if (l.type == LightSource::Type::Point) {
      render::SphereLight bulb;
      bulb.center = l.position.cast<float>();
      bulb.radius = static_cast<float>(l.radius);
      bulb.radiance = intensity;
      rig.sphere_lights.push_back(bulb);
    } else if (l.type == LightSource::Type::Ibl && !l.environment.empty()) {
      rig.environment = std::make_shared<render::EnvironmentLight>(l.environment, intensity);
      rig.environment->set_through_portals(l.through_windows);
    }
  }
  return rig;
}

render::LightRig SceneModel::light_rig() const { return make_light_rig(lights, false, windows); }

void SceneModel::validate() const {
  if (width <= 0 || height <= 0) throw std::runtime_error("scene model: no image size");
  for (double v : {fx, fy, cx, cy, camera_height_m, gamma})
    if (!std::isfinite(v)) throw std::runtime_error("scene model: non-finite camera number");
  require_in_range(fx, kFocalPxRange, "scene.json focal length K.fx");
  require_in_range(fy, kFocalPxRange, "scene.json focal length K.fy");
  require_in_range(camera_height_m, kCameraHeightRange, "scene.json camera_height_m");
  require_in_range(gamma, kResponseGammaRange, "scene.json gamma");
  if (!R_world_from_cam.allFinite()) throw std::runtime_error("scene model: non-finite rotation");
  for (const cv::Mat* m : {&depth, &albedo, &normals})
    if (!m->empty() && (m->cols != width || m->rows != height))
      throw std::runtime_error("scene model: a map's size differs from the image size");
  check_finite(depth, "depth");
  check_finite(albedo, "albedo");
  check_finite(normals, "normals");
  for (const auto& l : lights) {
    if (!l.intensity.allFinite() || !l.position.allFinite() || !l.corner.allFinite())
      throw std::runtime_error("scene model: non-finite light");
    for (int c = 0; c < 3; ++c) require_in_range(l.intensity[c], kLightIntensityRange, "scene.json light intensity");
    if (l.type == LightSource::Type::Point && !(l.radius >= kMinPointLightRadiusM && l.radius <= kMaxPointLightRadiusM))
      throw std::runtime_error("scene model: a point light's radius must lie in [1e-4, 2] m");
  }
  if (windows.size() > kMaxWindows) throw std::runtime_error("scene model: more windows than " + std::to_string(kMaxWindows));
  for (const Window& w : windows) {
    if (!w.corner.allFinite() || !as_portal(w).valid())
      throw std::runtime_error("scene model: a window is not finite or has no area");
  }
  if (!(imaging.blur_sigma_px >= 0 && imaging.blur_sigma_px <= kMaxImagingBlurPx))
    throw std::runtime_error("scene model: the imaging's blur must lie in [0, 8] px");
  for (const auto& bin : imaging.noise.sigma)
    for (float v : bin)
      if (!(v >= 0 && v <= kMaxImagingNoise)) throw std::runtime_error("scene model: the imaging's noise must lie in [0, 0.5]");
  const render::Defocus& d = imaging.defocus;
  if (!(d.base_sigma_px >= 0 && d.base_sigma_px <= kMaxImagingBlurPx))
    throw std::runtime_error("scene model: the defocus's base blur must lie in [0, 8] px");
  const bool dioptres_ok = d.focus_dioptres >= 0 && d.focus_dioptres <= kMaxDefocusDioptres && d.min_dioptres >= 0 &&
                           d.max_dioptres >= d.min_dioptres && d.max_dioptres <= kMaxDefocusDioptres;
  if (!dioptres_ok) throw std::runtime_error("scene model: the defocus's dioptres must lie in [0, 1000] 1/m, min <= max");
  if (!(d.sigma_px_per_dioptre >= 0 && d.sigma_px_per_dioptre <= kMaxDefocusPxPerDioptre))
    throw std::runtime_error("scene model: the defocus's growth must lie in [0, 1e4] px m");
  if (d.bands.size() > static_cast<size_t>(render::kDefocusBands))
    throw std::runtime_error("scene model: the defocus has more bands than " + std::to_string(render::kDefocusBands));
  for (const render::DepthBandBlur& b : d.bands)
    if (!(b.dioptres >= 0 && b.dioptres <= kMaxDefocusDioptres && b.sigma_px >= 0 && b.sigma_px <= kMaxImagingBlurPx &&
          b.edges >= 0))
      throw std::runtime_error("scene model: a defocus band out of range");
  if (hidden_facades.size() > kMaxHiddenFacades) throw std::runtime_error("scene model: too many hidden facades");
  for (const auto& f : hidden_facades) f.validate();
  enclosure.validate();
}

void save_scene(const SceneModel& scene, const std::string& folder) {
  scene.validate();
  fs::create_directories(fs::path(folder) / "lights");
  json j;
  j["format"] = "propcam-scene/1";
  j["image"] = {{"width", scene.width}, {"height", scene.height}};
  j["K"] = {{"fx", scene.fx}, {"fy", scene.fy}, {"cx", scene.cx}, {"cy", scene.cy}};
  json rot = json::array();
  for (int r = 0; r < 3; ++r)
    rot.push_back({scene.R_world_from_cam(r, 0), scene.R_world_from_cam(r, 1), scene.R_world_from_cam(r, 2)});
  j["R_world_from_cam"] = rot;
  j["camera_height_m"] = scene.camera_height_m;
  j["gamma"] = scene.gamma;
  j["indoor"] = scene.indoor;
  j["source_photo"] = scene.source_photo;
  json lights = json::array();
  int ibl_index = 0;
  for (const auto& l : scene.lights) {
    json lj = {{"type", to_string(l.type)}, {"intensity", vec(l.intensity)}};
    switch (l.type) {
      case LightSource::Type::Area:
        lj["position"] = vec(l.position);
        lj["corner"] = vec(l.corner);
        lj["edge_u"] = vec(l.edge_u);
        lj["edge_v"] = vec(l.edge_v);
        break;
      case LightSource::Type::Point:
        lj["position"] = vec(l.position);
        lj["radius"] = l.radius;
        break;
      case LightSource::Type::Sun: lj["direction"] = vec(l.direction); break;
      case LightSource::Type::Ibl: {
        const std::string file = l.file.empty() ? "lights/environment_" + std::to_string(ibl_index++) + ".exr" : l.file;
        capture::write_image((fs::path(folder) / file).string(), l.environment);
        lj["file"] = file;
        break;
      }
    }
    if (l.through_windows) lj["through_windows"] = true;
    lights.push_back(lj);
  }
  j["lights"] = lights;
  if (!scene.windows.empty()) {
    json windows = json::array();
    for (const Window& w : scene.windows)
      windows.push_back({{"corner", vec(w.corner)}, {"edge_u", vec(w.edge_u)}, {"edge_v", vec(w.edge_v)}});
    j["windows"] = windows;
  }
  json planes = json::array();
  for (const auto& p : scene.planes) {
    json pj = {{"name", p.name}, {"normal", vec(p.normal)}, {"offset", p.offset}};
    if (p.pixels > 0) {
      pj["extent_min"] = vec(p.extent_min);
      pj["extent_max"] = vec(p.extent_max);
      pj["pixels"] = p.pixels;
    }
    planes.push_back(pj);
  }
  j["planes"] = planes;
  json facades = json::array();
  for (const auto& f : scene.hidden_facades)
    facades.push_back({{"normal", vec(f.normal)}, {"offset", f.offset}, {"bottom_m", f.bottom_m}, {"top_m", f.top_m},
                       {"seen", {f.seen_min, f.seen_max}}, {"continued", {f.along_min, f.along_max}},
                       {"albedo", vec(f.albedo.cast<double>())}, {"pixels", f.pixels}});
  j["hidden_facades"] = facades;
  if (!scene.enclosure.empty())
    j["enclosure"] = {{"min", vec(scene.enclosure.min)}, {"max", vec(scene.enclosure.max)},
                      {"albedo", vec(scene.enclosure.albedo.cast<double>())}};
  j["imaging"] = imaging_json(scene.imaging);
  json reports = json::array();
  for (const auto& r : scene.reports) reports.push_back(to_json(r));
  j["reports"] = reports;
  const fs::path dir(folder);
  if (!scene.depth.empty()) capture::write_image((dir / "depth.exr").string(), scene.depth);
  if (!scene.albedo.empty()) capture::write_image((dir / "albedo.exr").string(), scene.albedo);
  if (!scene.normals.empty()) capture::write_image((dir / "normals.exr").string(), scene.normals);
  // scene.json last and atomically: a folder with scene.json is complete.
  const fs::path tmp = dir / ".scene.json.tmp";
  {
    std::ofstream out(tmp);
    out << j.dump(2) << "\n";
    if (!out) throw std::runtime_error("cannot write " + tmp.string());
  }
  fs::rename(tmp, dir / "scene.json");
}

SceneModel load_scene(const std::string& folder) {
  const fs::path dir(folder);
  std::ifstream in(dir / "scene.json");
  if (!in) throw std::runtime_error("no scene.json in '" + folder + "'");
  json j;
  try {
    in >> j;
  } catch (const json::exception& e) {
    throw std::runtime_error("cannot parse " + (dir / "scene.json").string() + ": " + e.what());
  }
  SceneModel s;
  try {
    s.width = json_int(j.at("image").at("width"), "image width");
    s.height = json_int(j.at("image").at("height"), "image height");
    s.fx = j.at("K").at("fx");
    s.fy = j.at("K").at("fy");
    s.cx = j.at("K").at("cx");
    s.cy = j.at("K").at("cy");
    const json& rot = j.at("R_world_from_cam");
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) s.R_world_from_cam(r, c) = rot.at(r).at(c);
    s.camera_height_m = j.at("camera_height_m");
    s.gamma = j.value("gamma", 2.2);
    s.indoor = j.value("indoor", true);
    s.source_photo = j.value("source_photo", "");
    for (const json& lj : j.at("lights")) {
      LightSource l;
      l.type = light_type_from_string(lj.at("type"));
      l.intensity = vec3(lj.at("intensity"), "intensity");
      if (lj.contains("position")) l.position = vec3(lj["position"], "position");
      if (lj.contains("direction")) l.direction = vec3(lj["direction"], "direction");
      if (l.type == LightSource::Type::Point) l.radius = lj.value("radius", kDefaultPointLightRadiusM);
      if (l.type == LightSource::Type::Area) {
        l.corner = vec3(lj.at("corner"), "corner");
        l.edge_u = vec3(lj.at("edge_u"), "edge_u");
        l.edge_v = vec3(lj.at("edge_v"), "edge_v");
      }
      if (l.type == LightSource::Type::Ibl) {
        l.file = lj.at("file");
        cv::Mat env = capture::read_image_float(file_inside(dir, l.file).string());
        if (env.channels() != 3) throw std::runtime_error("environment map must have 3 channels");
        l.environment = env;
      }
      l.through_windows = lj.value("through_windows", false);
      if (l.through_windows && l.type != LightSource::Type::Sun && l.type != LightSource::Type::Ibl)
        throw std::runtime_error("only a sun or an ibl light comes through windows");
      s.lights.push_back(l);
    }
    const json windows = j.value("windows", json::array());
    if (!windows.is_array() || windows.size() > kMaxWindows) throw std::runtime_error("bad windows list");
    for (const json& wj : windows)
      s.windows.push_back({vec3(wj.at("corner"), "window corner"), vec3(wj.at("edge_u"), "window edge_u"),
                           vec3(wj.at("edge_v"), "window edge_v")});
    for (const json& pj : j.value("planes", json::array())) {
      SupportPlane p{pj.at("name"), vec3(pj.at("normal"), "normal"), pj.at("offset")};
      if (pj.contains("pixels")) {
        p.pixels = json_int(pj.at("pixels"), "pixels");
        p.extent_min = vec3(pj.at("extent_min"), "extent_min");
        p.extent_max = vec3(pj.at("extent_max"), "extent_max");
        if (p.pixels < 0) throw std::runtime_error("a plane's pixel count is negative");
      }
      s.planes.push_back(p);
    }
    const json facades = j.value("hidden_facades", json::array());
    if (!facades.is_array() || facades.size() > kMaxHiddenFacades) throw std::runtime_error("bad hidden_facades list");
    for (const json& fj : facades) {
      HiddenFacade f;
      f.normal = vec3(fj.at("normal"), "normal");
      f.offset = fj.at("offset");
      f.bottom_m = fj.at("bottom_m");
      f.top_m = fj.at("top_m");
      f.seen_min = fj.at("seen").at(0);
      f.seen_max = fj.at("seen").at(1);
      f.along_min = fj.at("continued").at(0);
      f.along_max = fj.at("continued").at(1);
      f.albedo = vec3(fj.at("albedo"), "albedo").cast<float>();
      f.pixels = json_int(fj.at("pixels"), "pixels");
      s.hidden_facades.push_back(f);
    }
    if (j.contains("enclosure")) {
      const json& ej = j.at("enclosure");
      s.enclosure.min = vec3(ej.at("min"), "enclosure min");
      s.enclosure.max = vec3(ej.at("max"), "enclosure max");
      s.enclosure.albedo = vec3(ej.at("albedo"), "enclosure albedo").cast<float>();
      if (s.enclosure.empty()) throw std::runtime_error("the enclosure's max corner is not above its min");
    }
    if (j.contains("imaging")) s.imaging = imaging_from_json(j.at("imaging"));
    for (const json& rj : j.value("reports", json::array())) {
      StageReport r;
      r.stage = rj.value("stage", "");
      r.usable = rj.value("usable", true);
      r.why = rj.value("why", "");
      r.iterations = json_int_or(rj, "iterations", 0);
      r.seconds = rj.value("seconds", 0.0);
      r.error = rj.value("error", -1.0);
      r.details = rj.value("details", json::object());
      s.reports.push_back(r);
    }
  } catch (const json::exception& e) {
    throw std::runtime_error("bad scene.json in '" + folder + "': " + e.what());
  }
  auto load_map = [&](const char* name, int channels) {
    const fs::path p = dir / name;
    if (!fs::exists(p)) return cv::Mat();
    cv::Mat m = capture::read_image_float(p.string());
    if (m.channels() != channels) throw std::runtime_error(p.string() + " has the wrong channel count");
    return m;
  };
  s.depth = load_map("depth.exr", 1);
  s.albedo = load_map("albedo.exr", 3);
  s.normals = load_map("normals.exr", 3);
  s.validate();
  return s;
}

}  // namespace propcam::inference
