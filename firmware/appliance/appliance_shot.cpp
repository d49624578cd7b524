#include "appliance/appliance_shot.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <set>
#include <unistd.h>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include "propcam/capture/image_file.h"
#include "propcam/inference/infer.h"
#include "propcam/render/depth_mesh.h"
#include "propcam/render/depth_of_field.h"
#include "propcam/render/mesh_io.h"
#include "propcam/render/photo_imaging.h"
#include "propcam/render/placement.h"
#include "propcam/render/props.h"
#include "propcam/render/relight.h"
#include "propcam/render/transport_plan.h"
#include "common/working_size.h"

namespace propcam::firmware {
namespace fs = std::filesystem;
using appliance::Tier;

Analysis analyse_still(const cv::Mat& photo_linear, const cv::Mat& photo_rgb8, double camera_height_m,
                       long working_pixels, const std::function<void(const std::string&)>& on_stage,
                       const render::Vignetting& vignetting) {
  inference::InferenceOptions options;
  options.camera_height_m = camera_height_m;
  options.on_stage = on_stage;
  Analysis a;
  const cv::Size working = working_size(photo_linear.size(), working_pixels);
  if (working != photo_linear.size()) {
    a.full_photo_linear = photo_linear;
    a.photo_linear = reduce_to(photo_linear, working);
    a.photo_rgb8 = reduce_to(photo_rgb8, working);
  } else {
    a.photo_linear = photo_linear;
    a.photo_rgb8 = photo_rgb8;
  }
  a.vignetting = vignetting;
  a.scene = inference::infer_scene(render::devignette(a.photo_linear, vignetting), options);
  a.scene.source_photo = "appliance still";
  // Light is added in the photo's own linear space (its camera response undone).
  a.scene_photo = capture::srgb_linear_to_response_linear(a.photo_linear, a.scene.gamma);
  return a;
}

// ---------------------------------------------------------------- props
namespace {

// Samples of a preset's thumbnail render: enough for a small screen tile.
constexpr int kThumbnailSamples = 24;

std::string materials_of(const render::Mesh& mesh) {
  std::set<std::string> names;
  for (const auto& m : mesh.materials) names.insert(m.type == render::Material::Type::Plastic ? "glossy"
                                                    : m.type == render::Material::Type::Dielectric
                                                        ? "glass"
                                                        : render::to_string(m.type));
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : " + ") + n;
  return out;
}

cv::Mat load_rgb8(const fs::path& path) {
  cv::Mat bgr = cv::imread(path.string(), cv::IMREAD_COLOR);
  if (bgr.empty()) return {};
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return rgb;
}

// A cache file: written atomically under a per-process temporary name (two
// appliances sharing a data folder may render the same thumbnail at once),
// and a failed write only costs a re-render next time.
void save_rgb8(const fs::path& path, const cv::Mat& rgb) {
  try {
    capture::write_image(path.string(), rgb);
  } catch (const std::exception& e) {
    spdlog::warn("thumbnail cache: {}", e.what());
  }
}

cv::Mat thumbnail_for(const std::string& key, const fs::path& cache, int size,
                      const std::function<cv::Mat()>& render_linear) {
  fs::path file;
  if (!cache.empty()) {
    file = cache / (key + "-" + std::to_string(size) + ".png");
    if (fs::exists(file)) {
      cv::Mat cached = load_rgb8(file);
      if (cached.cols == size && cached.rows == size) return cached;
    }
  }
  cv::Mat rgb = capture::linear_to_srgb8(render_linear());
  if (!file.empty()) {
    std::error_code ec;
    fs::create_directories(cache, ec);
    save_rgb8(file, rgb);
  }
  return rgb;
}

// A file name fit for a cache key: letters, digits, '-', '_'.
std::string cache_key(const std::string& name) {
  std::string key;
  for (char c : name) key += std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' ? c : '_';
  return key.substr(0, 64);
}

}  // namespace

std::vector<PropEntry> list_props(const fs::path& thumbnail_cache, const fs::path& usb_root, int thumbnail_size) {
  std::vector<PropEntry> props;
  for (const auto& preset : render::prop_presets()) {
    PropEntry e;
    e.name = preset.name;
    e.source = preset.name;
    e.natural_height_m = preset.natural_height_m;
    e.material = materials_of(render::make_prop(preset.name));
    e.thumbnail = thumbnail_for("preset_" + preset.name, thumbnail_cache, thumbnail_size, [&] {
      return render::render_prop_thumbnail(preset.name, thumbnail_size, kThumbnailSamples);
    });
    props.push_back(std::move(e));
  }
  if (usb_root.empty()) return props;
  std::error_code ec;
  const fs::path dir = usb_root / "props";
  if (!fs::is_directory(dir, ec)) return props;
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    std::string ext = entry.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    if (entry.is_regular_file(ec) && ext == ".obj") files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  if (files.size() > static_cast<size_t>(kMaxUsbProps)) files.resize(kMaxUsbProps);
  for (const fs::path& file : files) {
    try {
      const render::Mesh mesh = render::load_mesh_file(file.string());
      PropEntry e;
      e.name = file.stem().string();
      e.source = file.string();
      e.from_usb = true;
      e.natural_height_m = mesh.bounds().sizes().y();
      e.material = materials_of(mesh);
      // Keyed by name and size so a changed file on the stick gets a new thumbnail.
      const std::string key = "usb_" + cache_key(e.name) + "_" + std::to_string(fs::file_size(file, ec));
      e.thumbnail = thumbnail_for(key, thumbnail_cache, thumbnail_size,
                                  [&] { return render::render_mesh_thumbnail(mesh, thumbnail_size, kThumbnailSamples); });
      props.push_back(std::move(e));
    } catch (const std::exception& ex) {
      spdlog::warn("props: {} left out: {}", file.string(), ex.what());
    }
  }
  return props;
}

// ---------------------------------------------------------------- placement
namespace {

constexpr int kSpotGridColumns = 4;
constexpr int kSpotGridRows = 3;
constexpr int kSpotSearchStridePx = 3;
// Spots are looked for below this share of the image height (above it a
// camera at eye level mostly sees walls and ceiling).
constexpr double kSpotTopFraction = 0.3;
constexpr double kSpotBottomFraction = 0.97;
// A spot's plane: its point lies within this of the plane.
constexpr double kPlaneMatchM = 0.06;

Eigen::Vector3d world_point(const render::PinholeCamera& camera, double u, double v, double z) {
  const Eigen::Vector3d p_cam((u - camera.cx) / camera.fx * z, (v - camera.cy) / camera.fy * z, z);
  return camera.R_world_from_cam * p_cam + camera.center_world;
}

}  // namespace

std::vector<Spot> find_spots(const inference::SceneModel& scene, int max_spots) {
  std::vector<Spot> spots;
  if (scene.depth.empty() || scene.normals.empty() || max_spots <= 0) return spots;
  const render::PinholeCamera camera = scene.camera();
  const double min_up = std::cos(render::kMaxSupportTiltDeg * 3.14159265358979323846 / 180.0);
  const int w = scene.depth.cols, h = scene.depth.rows;
  const int top = static_cast<int>(kSpotTopFraction * h), bottom = static_cast<int>(kSpotBottomFraction * h);
  struct Candidate {
    Spot spot;
    int row;
  };
  std::vector<Candidate> found;
  for (int gy = kSpotGridRows - 1; gy >= 0; --gy) {
    for (int gx = 0; gx < kSpotGridColumns; ++gx) {
      const int x0 = gx * w / kSpotGridColumns, x1 = (gx + 1) * w / kSpotGridColumns;
      const int y0 = top + gy * (bottom - top) / kSpotGridRows, y1 = top + (gy + 1) * (bottom - top) / kSpotGridRows;
      const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1);
      const double half_diagonal = 0.5 * std::hypot(x1 - x0, y1 - y0);
      double best_score = -1.0;
      cv::Point best;
      for (int y = y0; y < y1; y += kSpotSearchStridePx)
        for (int x = x0; x < x1; x += kSpotSearchStridePx) {
          const float z = scene.depth.at<float>(y, x);
          if (!std::isfinite(z) || z <= 0.f || z >= render::kSkyDepthM) continue;
          const cv::Vec3f n = scene.normals.at<cv::Vec3f>(y, x);
          if (!std::isfinite(n[1]) || n[1] < min_up) continue;
          // Flat and near the cell's centre.
          const double score = n[1] - 0.25 * std::hypot(x - cx, y - cy) / half_diagonal;
          if (score > best_score) {
            best_score = score;
            best = {x, y};
          }
        }
      if (best_score < 0.0) continue;
      Spot s;
      s.pixel = {static_cast<double>(best.x), static_cast<double>(best.y)};
      const Eigen::Vector3d p = world_point(camera, best.x, best.y, scene.depth.at<float>(best.y, best.x));
      s.distance_m = (p - camera.center_world).norm();
      s.surface = "surface";
      for (const auto& plane : scene.planes)
        if (std::abs(plane.normal.dot(p) + plane.offset) < kPlaneMatchM) {
          s.surface = plane.name;
          break;
        }
      found.push_back({s, kSpotGridRows - 1 - gy});
    }
  }
  // Nearest row first, each row left to right (the order NEXT walks them).
  std::stable_sort(found.begin(), found.end(), [](const Candidate& a, const Candidate& b) {
    return a.row != b.row ? a.row < b.row : a.spot.pixel.x < b.spot.pixel.x;
  });
  for (const auto& c : found) spots.push_back(c.spot);
  if (spots.size() > static_cast<size_t>(max_spots)) spots.resize(max_spots);
  // The spot nearest the lower middle of the image comes first.
  const cv::Point2d home(0.5 * w, 0.75 * h);
  const auto nearest = std::min_element(spots.begin(), spots.end(), [&](const Spot& a, const Spot& b) {
    return cv::norm(a.pixel - home) < cv::norm(b.pixel - home);
  });
  if (nearest != spots.end()) std::rotate(spots.begin(), nearest, spots.end());
  return spots;
}

std::vector<cv::Point2d> footprint_outline(const inference::SceneModel& scene, const Spot& spot,
                                           const render::Mesh& prop, double height_m) {
  std::vector<cv::Point2d> outline;
  if (scene.depth.empty()) return outline;
  const int u = std::clamp(static_cast<int>(std::lround(spot.pixel.x)), 0, scene.depth.cols - 1);
  const int v = std::clamp(static_cast<int>(std::lround(spot.pixel.y)), 0, scene.depth.rows - 1);
  const float z = scene.depth.at<float>(v, u);
  if (!std::isfinite(z) || z <= 0.f || z >= render::kSkyDepthM) return outline;
  const render::PinholeCamera camera = scene.camera();
  const Eigen::Vector3d base = world_point(camera, spot.pixel.x, spot.pixel.y, z);
  const Eigen::Vector3f size = prop.bounds().sizes();
  const double scale = height_m > 0 && size.y() > 0 ? height_m / size.y() : 1.0;
  // The prop faces the camera (yaw 0): its z axis points back at the lens, horizontally.
  Eigen::Vector3d to_camera = camera.center_world - base;
  to_camera.y() = 0;
  if (to_camera.norm() < 1e-6) return outline;
  const Eigen::Vector3d az = to_camera.normalized(), ax = Eigen::Vector3d::UnitY().cross(az);
  const double hx = 0.5 * scale * size.x(), hz = 0.5 * scale * size.z();
  for (const auto& [sx, sz] : {std::pair{-1, -1}, {1, -1}, {1, 1}, {-1, 1}}) {
    Eigen::Vector2d px;
    if (!camera.project(base + sx * hx * ax + sz * hz * az, px) || !px.allFinite()) return {};
    outline.emplace_back(px.x(), px.y());
  }
  return outline;
}

// ---------------------------------------------------------------- preview
namespace {

// The prop's base at the spot, at the prop's natural height (the preview and the render agree).
render::PropPlacement placement_at(const Spot& spot, double height_m) {
  render::PropPlacement p;
  p.pixel_u = spot.pixel.x;
  p.pixel_v = spot.pixel.y;
  p.height_m = height_m;
  return p;
}

double height_of(const PropEntry& prop, const render::Mesh& mesh) {
  return prop.natural_height_m > 0 ? prop.natural_height_m : natural_height(prop.source, mesh);
}

// The preview's shading: ambient plus a key from above and behind the camera.
constexpr float kPreviewAmbient = 0.35f;
constexpr float kPreviewKey = 0.65f;

}  // namespace

PlacementPreview::PlacementPreview(std::shared_ptr<const Analysis> analysis, const PropEntry& prop,
                                   const Spot& first_spot)
    : analysis_(std::move(analysis)), prop_source_(prop.source) {
  prop_ = load_prop(prop.source);
  height_m_ = height_of(prop, prop_);
  world_ = build_composite_world(analysis_->scene, prop_, placement_at(first_spot, height_m_));
}

cv::Mat PlacementPreview::render(const Spot& spot) {
  cv::Mat out = analysis_->photo_rgb8.clone();
  try {
    const render::PlacedProp placed = place_near_level_support(prop_, world_.camera, *world_.scene, placement_at(spot, height_m_));
    world_.scene->set_prop_transform(world_.prop_index, placed.world_from_prop);
  } catch (const std::invalid_argument&) {
    return out;  // no support there: the photo alone
  }
  const render::PrimaryBuffers primary = render::render_primary_buffers(*world_.scene, world_.camera, true);
  const Eigen::Vector3f to_key = (world_.camera.R_world_from_cam * Eigen::Vector3d(0, -1, -1)).normalized().cast<float>();
  for (int y = 0; y < out.rows && y < primary.prop_coverage.rows; ++y)
    for (int x = 0; x < out.cols && x < primary.prop_coverage.cols; ++x) {
      if (!primary.prop_coverage.at<std::uint8_t>(y, x)) continue;
      const cv::Vec3f n = primary.normal.at<cv::Vec3f>(y, x), a = primary.albedo.at<cv::Vec3f>(y, x);
      const float lambert = std::max(0.f, n[0] * to_key.x() + n[1] * to_key.y() + n[2] * to_key.z());
      const float shade = kPreviewAmbient + kPreviewKey * lambert;
      cv::Vec3b& px = out.at<cv::Vec3b>(y, x);
      for (int k = 0; k < 3; ++k)
        px[k] = static_cast<std::uint8_t>(std::lround(255.f * capture::linear_to_srgb(std::clamp(a[k] * shade, 0.f, 1.f))));
    }
  return out;
}

// ---------------------------------------------------------------- tiers

TierSpec tier_spec(Tier tier) {
  TierSpec spec;
  spec.tier = tier;
  switch (tier) {
    case Tier::Draft:
      spec.max_samples_per_pixel = 16;
      spec.target_relative_error = 0.25;
      break;
    case Tier::Good:
      spec.max_samples_per_pixel = 64;
      spec.target_relative_error = 0.1;
      break;
    case Tier::Final:
      spec.max_samples_per_pixel = 256;
      spec.target_relative_error = 0.04;
      break;
  }
  return spec;
}

ThroughputModel::ThroughputModel(fs::path file) : file_(std::move(file)) {
  if (file_.empty()) return;
  std::ifstream in(file_);
  if (!in) return;
  try {
    const nlohmann::json j = nlohmann::json::parse(in);
    const double rate = j.at("pixel_samples_per_second").get<double>();
    if (std::isfinite(rate) && rate > 0) {
      rate_ = rate;
      measured_ = true;
    }
  } catch (const std::exception& e) {
    spdlog::warn("throughput: {} ignored: {}", file_.string(), e.what());
  }
}

double ThroughputModel::predict_seconds(double pixels, int samples_per_pixel) const {
  return std::max(0.0, pixels) * std::max(0, samples_per_pixel) / rate_;
}

void ThroughputModel::record(double pixel_samples, double seconds) {
  // Renders shorter than this are dominated by set-up, not tracing.
  constexpr double kMinMeasuredSeconds = 0.2;
  constexpr double kNewWeight = 0.5;
  if (!(seconds >= kMinMeasuredSeconds) || !(pixel_samples > 0) || !std::isfinite(pixel_samples)) return;
  const double measured = pixel_samples / seconds;
  rate_ = measured_ ? (1 - kNewWeight) * rate_ + kNewWeight * measured : measured;
  measured_ = true;
  if (file_.empty()) return;
  std::error_code ec;
  fs::create_directories(file_.parent_path(), ec);
  const fs::path tmp = file_.string() + ".tmp-" + std::to_string(::getpid());
  {
    std::ofstream out(tmp);
    out << nlohmann::json{{"pixel_samples_per_second", rate_}}.dump(2) << "\n";
    if (!out) return;
  }
  fs::rename(tmp, file_, ec);
}

// ---------------------------------------------------------------- rendering
namespace {

constexpr int kRenderBounces = 4;
constexpr std::uint64_t kRenderSeed = 0x5eed;

// Samples a tile needs to reach `target` error, from its error now (error ~ 1/sqrt(samples)).
double samples_needed(const render::TileStatus& t, double target) {
  if (t.samples <= 0 || t.relative_error <= target || target <= 0) return t.samples;
  const double ratio = t.relative_error / target;
  return t.samples * ratio * ratio;
}

}  // namespace

CompositeRender::CompositeRender(std::shared_ptr<const Analysis> analysis, const PropEntry& prop, const Spot& spot,
                                 TierSpec tier, int threads, double time_budget_seconds)
    : analysis_(std::move(analysis)), tier_(tier), time_budget_seconds_(time_budget_seconds) {
  prop_ = load_prop(prop.source);
  world_ = build_composite_world(analysis_->scene, prop_, placement_at(spot, height_of(prop, prop_)));
  render::RenderSettings base;
  base.max_bounces = kRenderBounces;
  base.seed = kRenderSeed;
  base.threads = threads;
  base.light_layers = true;  // relighting after the render
  plan_ = render::plan_transport(*world_.scene, world_.lights, base, {});
  render::SessionSettings settings;
  settings.render = plan_.settings;
  settings.render.light_layers = true;
  settings.max_samples_per_pixel = tier.max_samples_per_pixel;
  settings.target_relative_error = tier.target_relative_error;
  bool prop_emits = false;
  for (const render::SphereLight& l : world_.lights.sphere_lights) prop_emits = prop_emits || l.prop_only;
  settings.cull_tiles = !prop_emits;  // a lamp's light reaches every tile
  session_ = std::make_unique<render::RenderSession>(*world_.scene, world_.camera, plan_.lights,
                                                     analysis_->scene_photo, world_.prop_bounds, settings);
}

bool CompositeRender::run_pass(const std::atomic<bool>* cancel) {
  if (finished()) return false;
  const render::PassReport report = session_->run_pass(cancel);
  passes_.push_back(report);
  seconds_ += report.pass_seconds;
  return !report.cancelled;
}

bool CompositeRender::finished() const { return session_->finished() || out_of_time(); }

bool CompositeRender::out_of_time() const {
  return time_budget_seconds_ > 0 && !passes_.empty() && !session_->finished() &&
         seconds_ + session_->predicted_next_pass_seconds() > time_budget_seconds_;
}

double CompositeRender::pixel_samples() const {
  double total = 0;
  for (const auto& t : session_->tiles())
    if (t.affected) total += static_cast<double>(t.rect.area()) * t.samples;
  return total;
}

std::shared_ptr<const RenderSnapshot> CompositeRender::snapshot(bool final_layers) const {
  auto s = std::make_shared<RenderSnapshot>();
  s->composite = session_->composite();
  s->display = capture::response_linear_to_srgb_linear(s->composite, analysis_->scene.gamma);
  s->tiles = session_->tiles();
  int affected = 0, done = 0;
  double to_good = 0, to_done = 0, busy_seconds = 0;
  const double good_target = tier_spec(Tier::Good).target_relative_error;
  for (const auto& t : s->tiles) {
    if (!t.affected) {
      ++s->skipped_tiles;
      continue;
    }
    ++affected;
    busy_seconds += t.seconds;
    s->samples_per_pixel = std::max(s->samples_per_pixel, t.samples);
    if (t.done) ++done;
    if (t.samples <= 0) continue;
    const double per_sample = t.seconds / t.samples;
    to_good += per_sample * std::max(0.0, std::min<double>(samples_needed(t, good_target), tier_.max_samples_per_pixel) - t.samples);
    if (!t.done)
      to_done += per_sample * std::max(0.0, std::min<double>(samples_needed(t, tier_.target_relative_error),
                                                             tier_.max_samples_per_pixel) - t.samples);
  }
  s->converged_fraction = affected ? static_cast<double>(done) / affected : 1.0;
  s->elapsed_seconds = seconds_;
  // Tile seconds add up over threads; the wall clock runs that much slower.
  const double parallelism = seconds_ > 0 && busy_seconds > 0 ? std::max(1.0, busy_seconds / seconds_) : 1.0;
  if (!passes_.empty()) {
    s->seconds_to_good = to_good / parallelism;
    s->seconds_to_done = to_done / parallelism;
  }
  for (const auto& d : plan_.decisions)
    if (!d.simulated) s->skipped_effects.push_back("no " + d.effect);
  s->finished = finished();
  s->stopped_by_time_budget = out_of_time();
  s->prop_distance_m = world_.camera.world_to_camera(world_.placed.base_world.cast<double>()).z();
  s->base_pixel = {world_.placement.pixel_u, world_.placement.pixel_v};
  if (final_layers) {
    s->layers = render::layers_in_original_order(plan_, session_->light_layers());
    s->depth = world_.depth.clone();
    const render::PrimaryBuffers primary = render::render_primary_buffers(*world_.scene, world_.camera, true);
    primary.depth.copyTo(s->depth, primary.prop_coverage);
    if (!analysis_->full_photo_linear.empty()) {
      const render::PhotoImaging& imaging = analysis_->scene.imaging;
      s->full_size_coverage = full_size_prop_coverage(*world_.scene, world_.camera, s->layers.coverage,
                                                      analysis_->full_photo_linear.size(),
                                                      imaging.blur_measured ? imaging.blur_sigma_at(s->prop_distance_m) : 0.0);
    }
  }
  return s;
}

// ---------------------------------------------------------------- adjusting

Adjustment adjustment_from_steps(const std::array<int, appliance::kRelightParamCount>& steps, double prop_distance_m) {
  using appliance::RelightParam;
  auto step = [&](RelightParam p) { return steps[static_cast<size_t>(p)]; };
  Adjustment a;
  a.scene_ev = kEvPerStep * step(RelightParam::SceneLight);
  a.prop_ev = kEvPerStep * step(RelightParam::PropLight);
  const double prop_distance = std::isfinite(prop_distance_m) && prop_distance_m > 0 ? prop_distance_m : 2.0;
  a.focus_m = prop_distance * std::exp2(kFocusStopsPerStep * step(RelightParam::Focus));
  a.aperture_m = kApertureMetresPerStep * std::max(0, step(RelightParam::Aperture));
  return a;
}

std::string describe_step(appliance::RelightParam param, int step, double prop_distance_m) {
  std::array<int, appliance::kRelightParamCount> steps{};
  steps[static_cast<size_t>(param)] = step;
  const Adjustment a = adjustment_from_steps(steps, prop_distance_m);
  char text[48];
  switch (param) {
    case appliance::RelightParam::SceneLight: std::snprintf(text, sizeof text, "%+.2f EV", a.scene_ev); break;
    case appliance::RelightParam::PropLight: std::snprintf(text, sizeof text, "%+.2f EV", a.prop_ev); break;
    case appliance::RelightParam::Focus: std::snprintf(text, sizeof text, "%.2f m", a.focus_m); break;
    case appliance::RelightParam::Aperture:
      if (a.aperture_m <= 0) return "pinhole";
      std::snprintf(text, sizeof text, "%.0f mm", 1000 * a.aperture_m);
      break;
  }
  return text;
}

cv::Mat adjusted_composite(const Analysis& analysis, const RenderSnapshot& render, const Adjustment& adjustment) {
  const float scene_scale = static_cast<float>(std::exp2(adjustment.scene_ev));
  const float prop_scale = static_cast<float>(std::exp2(adjustment.prop_ev));
  cv::Mat out;
  if (!render.layers.change.empty() && !render.layers.coverage.empty()) {
    // The photo's light scaled as a whole; the prop's change (its own
    // shading, shadows and bounce light) scaled by both.
    const cv::Mat base = analysis.scene_photo * scene_scale;
    const render::LightScales scales(render.layers.change.size(), scene_scale * prop_scale);
    out = render::relight_prop(base, render.layers, scales);
  } else {
    out = render.composite * scene_scale;
  }
  // The photo's blur, the lens's fall-off and the photo's noise on the prop, once the render has ended (the
  // screen's progressive snapshots stay raw).
  if (!render.layers.coverage.empty()) {
    render::CameraMatchOptions match;
    match.prop_depth_m = render.prop_distance_m;
    match.vignetting = analysis.vignetting;
    match.vignetting_source = "the board's calibration";
    out = render::match_camera(analysis.scene_photo * scene_scale, out, render.layers.coverage, analysis.scene.imaging,
                               match, analysis.scene.gamma);
  }
  if (adjustment.aperture_m > 0 && !render.depth.empty()) {
    render::DepthOfField dof;
    dof.aperture_m = adjustment.aperture_m;
    dof.focus_distance_m = adjustment.focus_m;
    out = render::apply_depth_of_field(out, render.depth, analysis.scene.fx, dof);
  }
  return capture::response_linear_to_srgb_linear(out, analysis.scene.gamma);
}

cv::Mat exported_composite(const Analysis& analysis, const RenderSnapshot& render, const Adjustment& adjustment) {
  cv::Mat working = adjusted_composite(analysis, render, adjustment);
  if (analysis.full_photo_linear.empty()) return working;
  // Both in linear sRGB. Outside the prop the change is carried up as a
  // ratio, which is the same in the camera response's space.
  const cv::Mat coverage = render.layers.coverage.empty() ? cv::Mat(working.size(), CV_32F, cv::Scalar(0))
                                                          : render.layers.coverage;
  cv::Mat full = analysis.full_photo_linear.clone();
  FullSizeDelivery delivery(analysis.photo_linear, working, coverage, full.size());
  // Depth of field blurs the prop's edges anyway.
  if (adjustment.aperture_m <= 0) delivery.use_sharp_coverage(render.full_size_coverage);
  delivery.apply(full, 0);
  return full;
}

}  // namespace propcam::firmware
