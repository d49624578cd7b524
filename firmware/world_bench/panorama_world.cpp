#include "world_bench/panorama_world.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>

#include "tools/cache_key.h"
#include "common/compositor.h"
#include "common/progress.h"
#include "propcam/capture/image_file.h"
#include "propcam/inference/ibl_distance.h"
#include "propcam/inference/ibl_ranking.h"
#include "propcam/inference/light_classifier.h"
#include "propcam/render/depth_mesh.h"
#include "propcam/render/panorama.h"
#include "propcam/render/path_tracer.h"
#include "worlds/real_views.h"
#include "tools/scene_reference_builder.h"
#include "worlds/world_metrics.h"

namespace propcam::firmware {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

constexpr double kPi = std::numbers::pi;
constexpr double kRadToDeg = 180.0 / kPi;

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

double luminance(const cv::Vec3f& c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

// ---------------------------------------------------------------------------
// The catalogue: the 26 panoramas, their labels and where each trained model
// met them.

// The catalogue (blender_panoramas, pmndrs_panoramas, panorama_group) is
// scene_reference_builder.h's: the references and this world agree on groups.

struct Panorama {
  std::string name;   // "courtyard", "pmndrs_city", or a file's stem
  std::string file;
  bool indoor = false;
  bool pmndrs = false, blender = false;
  std::string group;  // leave-one-out group
};

std::string pmndrs_dir_of(const PanoramaWorldOptions& o) { return o.pmndrs_dir.empty() ? default_pmndrs_dir() : o.pmndrs_dir; }

bool same_dir(const fs::path& a, const fs::path& b) {
  std::error_code ec;
  if (fs::exists(a, ec) && fs::exists(b, ec)) return fs::equivalent(a, b, ec);
  return fs::absolute(a).lexically_normal() == fs::absolute(b).lexically_normal();
}

Panorama blender_panorama(const std::string& name, bool indoor) {
  Panorama p;
  p.name = name;
  p.file = panorama_path(name);
  p.indoor = indoor;
  p.blender = true;
  p.group = panorama_group(name);
  return p;
}

Panorama pmndrs_panorama(const std::string& stem, bool indoor, const std::string& dir) {
  Panorama p;
  p.name = "pmndrs_" + stem;
  p.file = (fs::path(dir) / (stem + ".exr")).string();
  p.indoor = indoor;
  p.pmndrs = true;
  p.group = panorama_group(p.name);
  return p;
}

// A name or a path (optionally "=indoor"/"=outdoor") to a panorama.
Panorama resolve_panorama(const std::string& spec, const std::string& pmndrs_dir) {
  std::string s = spec;
  std::optional<bool> label;
  if (const auto eq = s.rfind('='); eq != std::string::npos) {
    const std::string kind = s.substr(eq + 1);
    if (kind != "indoor" && kind != "outdoor") throw std::invalid_argument("panorama '" + spec + "': the label must be =indoor or =outdoor");
    label = kind == "indoor";
    s = s.substr(0, eq);
  }
  const bool is_file = fs::path(s).has_extension();  // "pmndrs/city" is a name, "x.exr" a file
  if (!is_file) {
    std::string stem = s;
    bool pm = false;
    for (const char* prefix : {"pmndrs_", "pmndrs/"})
      if (stem.rfind(prefix, 0) == 0) stem = stem.substr(7), pm = true;
    if (pm) {
      for (const auto& [n, indoor] : pmndrs_panoramas())
        if (n == stem) return pmndrs_panorama(n, indoor, pmndrs_dir);
      throw std::invalid_argument("no pmndrs panorama '" + stem + "' (apartment, bridge, ... venice)");
    }
    for (const auto& [n, indoor] : blender_panoramas())
      if (n == stem) return blender_panorama(n, indoor);
    throw std::invalid_argument("no panorama '" + s + "': a blender-data name (city, courtyard, forest, interior, night, studio, "
                                "sunrise, sunset), pmndrs_<name>, or an EXR path");
  }
  const fs::path file(s);
  const std::string stem = file.stem().string();
  if (same_dir(file.parent_path(), pmndrs_dir))
    for (const auto& [n, indoor] : pmndrs_panoramas())
      if (n == stem) return pmndrs_panorama(n, indoor, pmndrs_dir);
  if (same_dir(file.parent_path(), kBlenderWorldDir))
    for (const auto& [n, indoor] : blender_panoramas())
      if (n == stem) return blender_panorama(n, indoor);
  Panorama p;  // a panorama no model has seen
  p.name = stem;
  p.file = s;
  p.indoor = label.value_or(false);
  p.group = stem;
  return p;
}

std::vector<Panorama> all_panoramas(const std::string& pmndrs_dir) {
  std::vector<Panorama> out;
  for (const auto& [n, indoor] : blender_panoramas()) out.push_back(blender_panorama(n, indoor));
  for (const auto& [n, indoor] : pmndrs_panoramas()) out.push_back(pmndrs_panorama(n, indoor, pmndrs_dir));
  return out;
}

// The catalogue name of a training spec's panorama string (a blender-data
// name, or a file), or "" when it is neither of the 26.
std::string catalogue_name(const std::string& spec_entry, const std::string& pmndrs_dir) {
  try {
    const Panorama p = resolve_panorama(spec_entry, pmndrs_dir);
    return p.blender || p.pmndrs ? p.name : "";
  } catch (const std::exception&) {
    return "";
  }
}

// The IBL library's entry name of a catalogue panorama (ibl_library.cpp).
std::string ranker_entry_name(const Panorama& p) {
  if (p.blender) return "blender_" + p.name;
  if (p.pmndrs) return "file_" + p.name.substr(7);
  return "";
}

// Every catalogue panorama of a group.
std::vector<Panorama> group_members(const std::string& group, const std::string& pmndrs_dir) {
  std::vector<Panorama> out;
  for (const auto& p : all_panoramas(pmndrs_dir))
    if (p.group == group) out.push_back(p);
  return out;
}

cv::Mat load_panorama_rgb3(const std::string& file) {
  if (!fs::exists(file)) throw std::runtime_error("panorama file " + file + " does not exist");
  const cv::Mat image = capture::read_image_float(file);
  if (image.channels() == 3) return image;
  std::vector<cv::Mat> ch;
  cv::split(image, ch);
  if (ch.size() < 3) throw std::runtime_error("panorama '" + file + "' has fewer than three channels");
  cv::Mat rgb;
  cv::merge(std::vector<cv::Mat>{ch[0], ch[1], ch[2]}, rgb);
  return rgb;
}

// ---------------------------------------------------------------------------
// Leave one out: the light classifier.

json classifier_spec_json(const LightTrainingSpec& s) {
  return {{"views_per_turn", s.views_per_turn}, {"pitches_deg", s.pitches_deg}, {"fov_deg", s.horizontal_fov_deg},
          {"size", {s.width, s.height}}, {"work_width", s.classifier.work_width},
          {"superpixel_px", s.classifier.superpixel_px}};
}

// One panorama's labelled superpixels, computed once and cached on disk
// (they do not depend on which panorama is left out).
inference::LabelledFeatures panorama_features(const std::string& entry, const LightTrainingSpec& spec,
                                              const fs::path& dir) {
  const std::string file = panorama_entry_file(entry);
  json key = classifier_spec_json(spec);
  key["file"] = fs::absolute(file).lexically_normal().string();
  key["bytes"] = file_stamp(file);
  std::string id = fs::path(file).stem().string() + "_" + std::to_string(std::hash<std::string>{}(key.dump()) % 100000007);
  const fs::path path = dir / (id + ".bin"), key_path = dir / (id + ".json");
  // Raw binary (exact floats): rows, cols, then the CV_32F features and the CV_32S labels.
  inference::LabelledFeatures f;
  if (key_matches(key_path, key)) {
    std::ifstream in(path, std::ios::binary);
    int32_t shape[2] = {0, 0};
    in.read(reinterpret_cast<char*>(shape), sizeof shape);
    if (in && shape[0] > 0 && shape[1] > 0 && shape[0] < (1 << 24) && shape[1] < (1 << 16)) {
      f.features.create(shape[0], shape[1], CV_32F);
      f.labels.create(shape[0], 1, CV_32S);
      in.read(reinterpret_cast<char*>(f.features.data), static_cast<std::streamsize>(f.features.total() * sizeof(float)));
      in.read(reinterpret_cast<char*>(f.labels.data), static_cast<std::streamsize>(f.labels.total() * sizeof(int32_t)));
      if (in) return f;
    }
  }
  const cv::Mat latlong = load_panorama_rgb3(file);
  f = inference::labelled_features(inference::panorama_views(latlong, spec.views_per_turn, spec.pitches_deg,
                                                             spec.horizontal_fov_deg, spec.width, spec.height),
                                   spec.classifier);
  if (f.features.empty() || f.features.type() != CV_32F || !f.features.isContinuous() || f.labels.type() != CV_32S ||
      !f.labels.isContinuous() || f.labels.total() != static_cast<size_t>(f.features.rows))
    return f;  // nothing to keep
  fs::create_directories(dir);
  const fs::path tmp = dir / (id + ".bin.tmp");
  {
    std::ofstream out(tmp, std::ios::binary);
    const int32_t shape[2] = {f.features.rows, f.features.cols};
    out.write(reinterpret_cast<const char*>(shape), sizeof shape);
    out.write(reinterpret_cast<const char*>(f.features.data), static_cast<std::streamsize>(f.features.total() * sizeof(float)));
    out.write(reinterpret_cast<const char*>(f.labels.data), static_cast<std::streamsize>(f.labels.total() * sizeof(int32_t)));
    if (!out) throw std::runtime_error("cannot write " + tmp.string());
  }
  fs::rename(tmp, path);
  write_key(key_path, key);
  return f;
}

// train_light_classifier's training set, with the panoramas of `skip` left
// out (the spec's Blender photos, if any, all kept: they are no panorama's).
inference::LightClassifier train_without(const LightTrainingSpec& spec, const std::set<std::string>& skip_entries,
                                         const fs::path& feature_dir, Progress& progress) {
  std::vector<inference::LabelledFeatures> panoramas;
  for (const auto& entry : spec.panoramas) {
    if (skip_entries.count(entry)) continue;
    progress.stage("leave one out: light classifier features of " + entry);
    panoramas.push_back(panorama_features(entry, spec, feature_dir));
  }
  std::vector<const inference::LabelledFeatures*> kept;
  for (const auto& f : panoramas) kept.push_back(&f);
  progress.stage("leave one out: training the light classifier");
  return train_light_classifier_on(kept, blender_light_groups(spec), spec);
}

// ---------------------------------------------------------------------------
// Leave one out: the IBL ranker.

json ibl_set_key(const IblTrainingSpec& s) {
  json extras = json::array();
  for (const auto& e : s.library.extra_panoramas)
    extras.push_back({fs::absolute(e.path).lexically_normal().string(), inference::to_string(e.kind), file_stamp(e.path)});
  return {{"library_width", s.library.width}, {"blender_dir", s.library.blender_dir},
          {"skies", s.library.procedural_skies}, {"rooms", s.library.procedural_rooms}, {"extras", extras},
          {"views_per_entry", s.views_per_entry}, {"max_abs_pitch_deg", s.max_abs_pitch_deg},
          {"fov", {s.min_fov_deg, s.max_fov_deg}}, {"size", {s.width, s.height}}, {"seed", s.seed},
          // The training set's features use the committed classifier and scene references.
          {"classifier", file_stamp(inference::default_light_classifier_path())},
          {"scene_refs", file_stamp(inference::default_scene_reference_path())}};
}

json ibl_train_key(const IblTrainingSpec& s) {
  return {{"set", ibl_set_key(s)}, {"pairs_per_query", s.pairs_per_query}, {"better_from_nearest", s.better_from_nearest},
          {"C", s.svm.C}, {"epsilon", s.svm.epsilon}, {"max_iterations", s.svm.max_iterations},
          {"max_qp_iterations", s.svm.max_qp_iterations}};
}

// The training set, kept on disk: the ranker (entries and views with their
// features) and the similarity and distance matrices (binary doubles).
void save_training_set(const IblTrainingSet& set, const fs::path& dir, const json& key) {
  fs::create_directories(dir);
  set.ranker.save((dir / "ranker.yml.gz").string());
  const size_t n = set.ranker.views.size();
  const fs::path tmp = dir / "matrices.bin.tmp";
  {
    std::ofstream out(tmp, std::ios::binary);
    const uint64_t header[2] = {0x50574942'4c534554ull, n};
    out.write(reinterpret_cast<const char*>(header), sizeof header);
    for (size_t q = 0; q < n; ++q)
      for (size_t j = 0; j < n; ++j) out.write(reinterpret_cast<const char*>(set.similarity[q][j].data()), sizeof(double) * inference::kIblSimilarityCount);
    for (size_t q = 0; q < n; ++q)
      for (size_t j = 0; j < n; ++j) {
        const double d = set.distance(q, j);
        out.write(reinterpret_cast<const char*>(&d), sizeof d);
      }
    out.write(reinterpret_cast<const char*>(&set.seconds), sizeof set.seconds);
    if (!out) throw std::runtime_error("cannot write " + tmp.string());
  }
  fs::rename(tmp, dir / "matrices.bin");
  write_key(dir / "key.json", key);
}

bool load_training_set(IblTrainingSet& set, const fs::path& dir, const json& key) {
  if (!key_matches(dir / "key.json", key)) return false;
  try {
    set.ranker = inference::IblRanker::load((dir / "ranker.yml.gz").string());
    std::ifstream in(dir / "matrices.bin", std::ios::binary);
    uint64_t header[2] = {0, 0};
    in.read(reinterpret_cast<char*>(header), sizeof header);
    const size_t n = set.ranker.views.size();
    if (!in || header[0] != 0x50574942'4c534554ull || header[1] != n) return false;
    set.similarity.assign(n, std::vector<inference::IblSimilarity>(n));
    for (size_t q = 0; q < n; ++q)
      for (size_t j = 0; j < n; ++j)
        in.read(reinterpret_cast<char*>(set.similarity[q][j].data()), sizeof(double) * inference::kIblSimilarityCount);
    set.distance.resize(n, n);
    for (size_t q = 0; q < n; ++q)
      for (size_t j = 0; j < n; ++j) in.read(reinterpret_cast<char*>(&set.distance(q, j)), sizeof(double));
    in.read(reinterpret_cast<char*>(&set.seconds), sizeof set.seconds);
    return static_cast<bool>(in);
  } catch (const std::exception&) {
    return false;
  }
}

// The set without the entries named in `drop` (views and indices remapped).
IblTrainingSet without_entries(const IblTrainingSet& set, const std::set<std::string>& drop) {
  IblTrainingSet out;
  out.seconds = set.seconds;
  std::vector<int> entry_map(set.ranker.entries.size(), -1);
  for (size_t e = 0; e < set.ranker.entries.size(); ++e)
    if (!drop.count(set.ranker.entries[e].name)) {
      entry_map[e] = static_cast<int>(out.ranker.entries.size());
      out.ranker.entries.push_back(set.ranker.entries[e]);
    }
  std::vector<size_t> kept;
  for (size_t v = 0; v < set.ranker.views.size(); ++v) {
    const int e = set.ranker.views[v].entry;
    if (e < 0 || e >= static_cast<int>(entry_map.size()) || entry_map[e] < 0) continue;
    inference::IblRankerView view = set.ranker.views[v];
    view.entry = entry_map[e];
    out.ranker.views.push_back(std::move(view));
    kept.push_back(v);
  }
  const size_t n = kept.size();
  out.similarity.assign(n, std::vector<inference::IblSimilarity>(n));
  out.distance.resize(n, n);
  for (size_t a = 0; a < n; ++a)
    for (size_t b = 0; b < n; ++b) {
      out.similarity[a][b] = set.similarity[kept[a]][kept[b]];
      out.distance(a, b) = set.distance(kept[a], kept[b]);
    }
  return out;
}


// ---------------------------------------------------------------------------
// The probe.

constexpr const char* kSphereNames[3] = {"diffuse", "rough_metal", "mirror"};

// A UV sphere (outward, counter-clockwise, smooth normals) of `radius` at `centre`.
void add_sphere(render::Mesh& mesh, const Eigen::Vector3f& centre, float radius, int material) {
  constexpr int kSegments = 64, kRings = 32;
  const int base = static_cast<int>(mesh.positions.size());
  for (int i = 0; i <= kRings; ++i) {
    const float theta = static_cast<float>(kPi) * i / kRings;
    for (int j = 0; j <= kSegments; ++j) {
      const float phi = 2.f * static_cast<float>(kPi) * j / kSegments;
      const Eigen::Vector3f n(std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi));
      mesh.positions.push_back(centre + radius * n);
      mesh.normals.push_back(n);
    }
  }
  const auto at = [&](int i, int j) { return base + i * (kSegments + 1) + j; };
  const auto add = [&](int a, int b, int c) {
    const Eigen::Vector3f& pa = mesh.positions[a];
    const Eigen::Vector3f cross = (mesh.positions[b] - pa).cross(mesh.positions[c] - pa);
    if (cross.norm() < 1e-12f) return;  // the poles' collapsed triangles
    const Eigen::Vector3f mid = (pa + mesh.positions[b] + mesh.positions[c]) / 3.f - centre;
    if (cross.dot(mid) < 0) std::swap(b, c);
    mesh.triangles.emplace_back(a, b, c);
    mesh.material_ids.push_back(material);
  };
  for (int i = 0; i < kRings; ++i)
    for (int j = 0; j < kSegments; ++j) {
      add(at(i, j), at(i + 1, j), at(i + 1, j + 1));
      add(at(i, j), at(i + 1, j + 1), at(i, j + 1));
    }
}

// The sphere centres in prop space: a row along x, standing on y = 0.
std::array<Eigen::Vector3f, 3> sphere_centres(const PanoramaWorldOptions& o) {
  const float r = static_cast<float>(o.sphere_radius_m), step = static_cast<float>(2 * o.sphere_radius_m + o.sphere_gap_m);
  return {Eigen::Vector3f(-step, r, 0), Eigen::Vector3f(0, r, 0), Eigen::Vector3f(step, r, 0)};
}

render::Mesh probe_mesh(const PanoramaWorldOptions& o) {
  render::Mesh mesh;
  render::Material diffuse;
  diffuse.type = render::Material::Type::Diffuse;
  diffuse.name = kSphereNames[0];
  diffuse.albedo = Eigen::Vector3f::Constant(0.8f);
  render::Material rough;
  rough.type = render::Material::Type::Metal;
  rough.name = kSphereNames[1];
  rough.albedo = Eigen::Vector3f::Constant(0.9f);
  rough.roughness = static_cast<float>(o.rough_metal_alpha);
  render::Material mirror = rough;
  mirror.name = kSphereNames[2];
  mirror.roughness = static_cast<float>(o.mirror_alpha);
  mesh.materials = {diffuse, rough, mirror};
  const auto centres = sphere_centres(o);
  for (int k = 0; k < 3; ++k) add_sphere(mesh, centres[k], static_cast<float>(o.sphere_radius_m), k);
  mesh.validate();
  return mesh;
}

// Nearest hit of the ray through continuous pixel (u, v) among the spheres
// (camera frame): the sphere's index, or -1.
int sphere_hit(const render::PinholeCamera& cam, const std::array<Eigen::Vector3d, 3>& centres, double radius, double u,
               double v) {
  const Eigen::Vector3d d = Eigen::Vector3d((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0).normalized();
  int best = -1;
  double best_t = INFINITY;
  for (int k = 0; k < 3; ++k) {
    const double b = d.dot(centres[k]);
    const double disc = b * b - (centres[k].squaredNorm() - radius * radius);
    if (disc < 0) continue;
    const double t = b - std::sqrt(disc);
    if (t > 0 && t < best_t) best_t = t, best = k;
  }
  return best;
}

// CV_8U: k+1 on the pixels whose whole footprint (centre and corners) sees sphere k.
cv::Mat sphere_masks(const render::PinholeCamera& cam, const std::array<Eigen::Vector3d, 3>& centres, double radius) {
  cv::Mat mask(cam.height, cam.width, CV_8U, cv::Scalar(0));
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const int k = sphere_hit(cam, centres, radius, x, y);
      if (k < 0) continue;
      bool whole = true;
      for (int c = 0; c < 4 && whole; ++c)
        whole = sphere_hit(cam, centres, radius, x + (c & 1 ? 0.5 : -0.5), y + (c & 2 ? 0.5 : -0.5)) == k;
      if (whole) mask.at<uint8_t>(y, x) = static_cast<uint8_t>(k + 1);
    }
  return mask;
}

cv::Mat clip01(const cv::Mat& m) {
  cv::Mat out;
  cv::min(cv::max(m, 0.0), 1.0, out);
  cv::patchNaNs(out, 0.0);
  return out;
}

cv::Mat to_display(const cv::Mat& linear01) {
  cv::Mat out(linear01.size(), CV_32FC3);
  for (int y = 0; y < out.rows; ++y)
    for (int x = 0; x < out.cols; ++x) {
      const cv::Vec3f c = linear01.at<cv::Vec3f>(y, x);
      out.at<cv::Vec3f>(y, x) = cv::Vec3f(capture::linear_to_srgb(c[0]), capture::linear_to_srgb(c[1]), capture::linear_to_srgb(c[2]));
    }
  return out;
}

double angle_deg_or_nan(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  if (!(a.norm() > 0) || !(b.norm() > 0) || !a.allFinite() || !b.allFinite()) return NAN;
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * kRadToDeg;
}

// Candidate pixels, best first: the bottom centre, then around it.
std::vector<Eigen::Vector2d> probe_candidates(int width, int height) {
  std::vector<Eigen::Vector2d> out;
  for (double fv : {0.85, 0.78, 0.92, 0.7, 0.62})
    for (double fu : {0.5, 0.38, 0.62, 0.26, 0.74})
      out.emplace_back(fu * (width - 1), fv * (height - 1));
  return out;
}

json number_or_null(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

double median(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return NAN;
  const size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + m, v.end());
  const double hi = v[m];
  if (v.size() % 2) return hi;
  return 0.5 * (hi + *std::max_element(v.begin(), v.begin() + m));
}

json moments_json(const LightMoments& m) {
  return {{"vector", {m.vector.x(), m.vector.y(), m.vector.z()}}, {"irradiance_up", m.irradiance_up}, {"total", m.total}};
}

}  // namespace

// ---------------------------------------------------------------------------


std::vector<std::string> panorama_world_names() {
  std::vector<std::string> out;
  for (const auto& [n, indoor] : blender_panoramas()) out.push_back(n);
  for (const auto& [n, indoor] : pmndrs_panoramas()) out.push_back("pmndrs_" + n);
  return out;
}

LightTrainingSpec committed_light_training_spec(const std::string& pmndrs_dir, const std::string& blender_world) {
  LightTrainingSpec spec;  // scripts/train_light_classifier.sh: the defaults, all 26 panoramas, the Blender world
  spec.panoramas = default_training_panoramas();
  for (const auto& [n, indoor] : pmndrs_panoramas()) spec.panoramas.push_back((fs::path(pmndrs_dir) / (n + ".exr")).string());
  // The script lists "$extra"/*.exr: the shell's sorted order, not the table's.
  std::sort(spec.panoramas.begin() + static_cast<long>(default_training_panoramas().size()), spec.panoramas.end());
  if (fs::exists(fs::path(blender_world) / "world.json")) spec.blender_world = blender_world;
  spec.quiet = true;
  return spec;
}

IblTrainingSpec committed_ibl_training_spec(const std::string& pmndrs_dir) {
  IblTrainingSpec spec;  // scripts/train_ibl_ranker.sh: indoor ones first, then outdoor, each in its list's order
  for (bool indoor : {true, false})
    for (const auto& [n, in] : pmndrs_panoramas())
      if (in == indoor)
        spec.library.extra_panoramas.push_back(
            {(fs::path(pmndrs_dir) / (n + ".exr")).string(), indoor ? inference::SceneKind::Indoor : inference::SceneKind::Outdoor});
  spec.quiet = true;
  return spec;
}

std::vector<PanoramaView> make_panorama_views(const PanoramaWorldOptions& o) {
  if (o.views_per_panorama < 1) throw std::invalid_argument("views_per_panorama must be at least 1");
  const std::string pmndrs_dir = pmndrs_dir_of(o);
  std::vector<Panorama> panoramas;
  if (o.panoramas.empty()) panoramas = all_panoramas(pmndrs_dir);
  else
    for (const auto& s : o.panoramas) panoramas.push_back(resolve_panorama(s, pmndrs_dir));
  std::vector<PanoramaView> views;
  for (const auto& p : panoramas) {
    if (!fs::exists(p.file))
      throw std::runtime_error("panorama '" + p.name + "': " + p.file + " does not exist" +
                               (p.pmndrs ? " (run `bash scripts/fetch_pmndrs_hdri.sh` to fetch and decode the pmndrs panoramas)"
                                         : p.blender ? " (Debian's blender-data package installs it)" : ""));
    const cv::Mat latlong = load_panorama_rgb3(p.file);
    for (int i = 0; i < o.views_per_panorama; ++i) {
      const double yaw = std::fmod(o.yaw_offset_deg + 360.0 * i / o.views_per_panorama + 360.0, 360.0);
      const double pitch = o.views_per_panorama == 1 ? 0.5 * (o.pitch_first_deg + o.pitch_last_deg)
                                                     : o.pitch_first_deg + (o.pitch_last_deg - o.pitch_first_deg) * i /
                                                                               (o.views_per_panorama - 1);
      const render::ViewSpec spec = render::view_spec(yaw, pitch, o.horizontal_fov_deg, o.width, o.height);
      PanoramaView v;
      v.panorama = p.name;
      v.group = p.group;
      v.indoor = p.indoor;
      v.known = p.blender || p.pmndrs;
      v.panorama_file = p.file;
      v.yaw_deg = yaw;
      v.pitch_deg = pitch;
      char name[64];
      std::snprintf(name, sizeof name, "_yaw%.0f", yaw);
      v.name = p.name + name;
      // shoot_panorama_view's steps (real_views.cpp), keeping the exposure.
      v.camera = render::view_camera(spec);
      cv::Mat linear = render::rectilinear_view(latlong, v.camera);
      v.exposure = render::auto_expose(linear);
      v.emitters = cv::Mat(linear.size(), CV_8U, cv::Scalar(0));
      for (int y = 0; y < linear.rows; ++y)
        for (int x = 0; x < linear.cols; ++x)
          if (luminance(linear.at<cv::Vec3f>(y, x)) >= 4.0) v.emitters.at<uint8_t>(y, x) = 255;
      v.photo_linear = capture::srgb8_to_linear(capture::linear_to_srgb8(linear));
      views.push_back(std::move(v));
    }
  }
  return views;
}

inference::InferenceOptions leave_one_out_options(const PanoramaView& view, const PanoramaWorldOptions& o,
                                                  inference::InferenceOptions base, json* report) {
  json r = {{"leave_one_out", o.leave_one_out}, {"group", view.group}};
  if (!o.leave_one_out || !view.known) {
    r["why"] = o.leave_one_out ? "a panorama none of the committed models saw: they are used as they are"
                               : "leave-one-out off: the committed models";
    if (report) *report = r;
    return base;
  }
  const std::string pmndrs_dir = pmndrs_dir_of(o);
  const std::vector<Panorama> members = group_members(view.group, pmndrs_dir);
  const fs::path cache = fs::path(o.cache_dir);
  const fs::path dir = cache / view.group;
  Progress progress(o.quiet);

  // Scene-class references: views of every catalogued panorama, grouped as
  // this world groups them (scene_reference_builder.cpp).
  base.scene_class_left_out = view.group;
  r["scene_class_left_out"] = view.group;

  // The light classifier.
  json classifier_used = "committed";
  {
    const LightTrainingSpec spec = o.light_training ? *o.light_training : committed_light_training_spec(pmndrs_dir);
    std::set<std::string> skip;
    std::vector<std::string> kept;
    for (const auto& entry : spec.panoramas) {
      const std::string name = catalogue_name(entry, pmndrs_dir);
      if (!name.empty() && panorama_group(name) == view.group) skip.insert(entry);
      else kept.push_back(entry);
    }
    json key = classifier_spec_json(spec);
    key["negative_stride"] = spec.negative_stride;
    key["trees"] = spec.trees;
    key["depth"] = spec.depth;
    key["panoramas"] = kept;
    if (!spec.blender_world.empty())
      key["blender_world"] = {fs::absolute(spec.blender_world).lexically_normal().string(),
                              file_stamp((fs::path(spec.blender_world) / "world.json").string()), spec.blender_copies};
    json part = {{"left_out", std::vector<std::string>(skip.begin(), skip.end())},
                 {"blender_world", spec.blender_world.empty() ? json("none")
                                                              : json(spec.blender_world)}};
    const fs::path model = dir / "light_classifier.yml.gz", key_path = dir / "light_classifier.json";
    if (!skip.empty()) classifier_used = key;
    if (skip.empty()) {
      part["why"] = "not in the classifier's training set: the committed model";
    } else if (key_matches(key_path, key) && fs::exists(model)) {
      base.lighting.light_classifier = model.string();
      part["path"] = model.string();
      part["cached"] = true;
      part["seconds"] = 0.0;
    } else {
      const auto t = std::chrono::steady_clock::now();
      const inference::LightClassifier c = train_without(spec, skip, cache / "features", progress);
      fs::create_directories(dir);
      c.save(model.string());
      write_key(key_path, key);
      base.lighting.light_classifier = model.string();
      part["path"] = model.string();
      part["cached"] = false;
      part["seconds"] = seconds_since(t);
    }
    r["light_classifier"] = part;
  }

  // The IBL ranker: its entries are the library's panoramas, its weights
  // trained on their views.
  {
    const IblTrainingSpec spec = o.ibl_training ? *o.ibl_training : committed_ibl_training_spec(pmndrs_dir);
    std::set<std::string> drop;
    for (const auto& m : members) drop.insert(ranker_entry_name(m));
    json key = {{"train", ibl_train_key(spec)}, {"drop", std::vector<std::string>(drop.begin(), drop.end())},
                {"strict", o.strict_ibl_features}};
    if (o.strict_ibl_features) key["models"] = {{"classifier", classifier_used}, {"refs_left_out", base.scene_class_left_out}};
    const std::string stem = o.strict_ibl_features ? "ibl_ranker_strict" : "ibl_ranker";
    const fs::path model = dir / (stem + ".yml.gz"), key_path = dir / (stem + ".json");
    json part = {{"left_out", std::vector<std::string>(drop.begin(), drop.end())}};
    if (key_matches(key_path, key) && fs::exists(model)) {
      base.lighting.ibl_ranker = model.string();
      part["path"] = model.string();
      part["cached"] = true;
      part["seconds"] = 0.0;
    } else {
      const auto t = std::chrono::steady_clock::now();
      IblTrainingSet reduced;
      if (o.strict_ibl_features) {
        // The views' features from this run's models: the classifier
        // trained without the panorama, the k-NN without its references.
        progress.stage("leave one out: the IBL ranker's training set without " + view.group);
        const inference::LightClassifier classifier = inference::LightClassifier::load(
            base.lighting.light_classifier.empty() ? inference::default_light_classifier_path() : base.lighting.light_classifier);
        reduced = build_ibl_training_set_with(spec, base, classifier, drop);
        part["training_set"] = "strict: features from the leave-one-out classifier and scene-class references";
        part["training_set_seconds"] = reduced.seconds;
      } else {
        IblTrainingSet set;
        const json set_key = ibl_set_key(spec);
        const fs::path set_dir = cache / "ibl_training_set";
        bool set_cached = load_training_set(set, set_dir, set_key);
        if (!set_cached) {
          progress.stage("leave one out: building the IBL ranker's training set (once)");
          IblTrainingSpec s = spec;
          s.quiet = o.quiet;
          set = build_ibl_training_set(s);
          save_training_set(set, set_dir, set_key);
        }
        part["training_set"] = "shared: features from the committed classifier and scene-class references";
        part["training_set_cached"] = set_cached;
        part["training_set_seconds"] = set_cached ? 0.0 : set.seconds;
        reduced = without_entries(set, drop);
        if (reduced.ranker.entries.size() == set.ranker.entries.size()) part["why"] = "not among the library's entries";
      }
      progress.stage("leave one out: training the IBL ranker without " + view.group);
      const inference::SvmRankResult w = train_ibl_weights(reduced, -1, spec);
      reduced.ranker.weights = w.w;
      fs::create_directories(dir);
      reduced.ranker.save(model.string());
      write_key(key_path, key);
      base.lighting.ibl_ranker = model.string();
      part["path"] = model.string();
      part["cached"] = false;
      part["converged"] = w.converged;
      part["seconds"] = seconds_since(t);
    }
    r["ibl_ranker"] = part;
  }
  if (report) *report = r;
  return base;
}

namespace {

// Each sphere's RMSE against the truth, and after the one scale (`si_scale`)
// that best fits the image to the truth over all three spheres.
void score_spheres(const cv::Mat& est, const cv::Mat& truth, const cv::Mat& mask, double& si_scale,
                   std::vector<SphereScore>& spheres) {
  double et = 0, ee = 0;
  for (int y = 0; y < mask.rows; ++y)
    for (int x = 0; x < mask.cols; ++x) {
      if (!mask.at<uint8_t>(y, x)) continue;
      const cv::Vec3f e = est.at<cv::Vec3f>(y, x), g = truth.at<cv::Vec3f>(y, x);
      for (int c = 0; c < 3; ++c) et += double(e[c]) * g[c], ee += double(e[c]) * e[c];
    }
  const double alpha = ee > 0 ? et / ee : 1.0;
  si_scale = alpha;
  for (int k = 0; k < 3; ++k) {
    SphereScore s;
    s.material = kSphereNames[k];
    double se = 0, sse = 0, le = 0, lt = 0;
    int n = 0;
    for (int y = 0; y < mask.rows; ++y)
      for (int x = 0; x < mask.cols; ++x) {
        if (mask.at<uint8_t>(y, x) != k + 1) continue;
        const cv::Vec3f e = est.at<cv::Vec3f>(y, x), g = truth.at<cv::Vec3f>(y, x);
        for (int c = 0; c < 3; ++c) {
          se += (double(e[c]) - g[c]) * (double(e[c]) - g[c]);
          sse += (alpha * e[c] - g[c]) * (alpha * e[c] - g[c]);
        }
        le += luminance(e), lt += luminance(g);
        ++n;
      }
    s.pixels = n;
    if (n > 0) {
      s.rmse = std::sqrt(se / (3.0 * n));
      s.si_rmse = std::sqrt(sse / (3.0 * n));
      s.mean_estimate = le / n, s.mean_truth = lt / n;
    }
    spheres.push_back(s);
  }
}

}  // namespace

ProbeResult score_light_probe(const PanoramaView& view, const inference::SceneModel& estimate,
                              const PanoramaWorldOptions& o) {
  ProbeResult result;
  const render::Mesh mesh = probe_mesh(o);
  const auto centres_prop = sphere_centres(o);
  const render::PinholeCamera est_camera = estimate.camera();
  const double radius = o.sphere_radius_m;
  constexpr int kMinSpherePixels = 6;

  // Where the probe stands: the first candidate that is a level support with all three spheres in the frame.
  std::optional<CompositeWorld> world;
  std::array<Eigen::Vector3d, 3> centres_cam;
  cv::Mat mask;
  std::vector<std::string> whys;
  for (const Eigen::Vector2d& px : probe_candidates(est_camera.width, est_camera.height)) {
    render::PropPlacement placement;
    placement.pixel_u = px.x();
    placement.pixel_v = px.y();
    try {
      CompositeWorld w = build_composite_world(estimate, mesh, placement);
      for (int k = 0; k < 3; ++k)
        centres_cam[k] = est_camera.world_to_camera((w.placed.world_from_prop * centres_prop[k]).cast<double>());
      bool in_front = true;
      for (const auto& c : centres_cam) in_front = in_front && c.z() > radius + 0.05;
      if (!in_front) {
        whys.push_back("at (" + std::to_string(int(px.x())) + "," + std::to_string(int(px.y())) + "): a sphere is behind the camera");
        continue;
      }
      cv::Mat m = sphere_masks(est_camera, centres_cam, radius);
      bool visible = true;
      for (int k = 0; k < 3; ++k) visible = visible && cv::countNonZero(m == k + 1) >= kMinSpherePixels;
      // All of each sphere inside the frame: none of its pixels touches the border.
      cv::Mat any = m > 0;
      const bool touches = cv::countNonZero(any.row(0)) + cv::countNonZero(any.row(any.rows - 1)) +
                               cv::countNonZero(any.col(0)) + cv::countNonZero(any.col(any.cols - 1)) > 0;
      if (!visible || touches) {
        whys.push_back("at (" + std::to_string(int(px.x())) + "," + std::to_string(int(px.y())) +
                       "): the spheres leave the frame or are too small");
        continue;
      }
      mask = m;
      world = std::move(w);
      break;
    } catch (const std::invalid_argument& e) {
      whys.push_back(e.what());
    }
  }
  if (!world) {
    result.why = "no level support for the probe: " + (whys.empty() ? std::string("no candidate") : whys.front());
    if (whys.size() > 1) result.why += " (and " + std::to_string(whys.size() - 1) + " more candidates refused)";
    return result;
  }
  result.placed = true;
  result.at = Eigen::Vector2d(world->placement.pixel_u, world->placement.pixel_v);
  result.mask = mask;

  const auto t = std::chrono::steady_clock::now();
  // The estimate: as `propcam composite` makes it.
  render::RenderSettings settings;
  settings.samples_per_pixel = o.spp;
  settings.max_bounces = o.bounces;
  settings.seed = o.seed;
  // The truth's spheres are rendered by our renderer, sharp and clean, and
  // the probe measures light: the camera match stays off on both sides.
  CompositeOptions options;
  options.match_camera = false;
  const auto composite_of = [&](const inference::SceneModel& scene) {
    const cv::Mat scene_photo = capture::srgb_linear_to_response_linear(view.photo_linear, scene.gamma);
    const CompositeResult composite = composite_prop(scene_photo, scene, mesh, world->placement, settings, options);
    return clip01(capture::response_linear_to_srgb_linear(composite.composite_linear, scene.gamma));
  };
  const cv::Mat est = composite_of(estimate);

  // The truth: the same spheres at the same place relative to the camera,
  // under the panorama alone (exposed as the photo), through the estimate's
  // intrinsics (pixel-aligned with the estimate) and the true orientation.
  const cv::Mat latlong = load_panorama_rgb3(view.panorama_file);
  render::LightRig truth_rig;
  truth_rig.environment = std::make_shared<render::EnvironmentLight>(latlong, Eigen::Vector3f::Constant(static_cast<float>(view.exposure)));
  render::PinholeCamera truth_camera = est_camera;
  truth_camera.R_world_from_cam = view.camera.R_world_from_cam;
  truth_camera.center_world = view.camera.center_world;
  Eigen::Affine3d true_world_from_cam = Eigen::Affine3d::Identity();
  true_world_from_cam.linear() = truth_camera.R_world_from_cam;
  true_world_from_cam.translation() = truth_camera.center_world;
  Eigen::Affine3d est_cam_from_world = Eigen::Affine3d::Identity();
  est_cam_from_world.linear() = est_camera.R_world_from_cam.transpose();
  est_cam_from_world.translation() = -(est_camera.R_world_from_cam.transpose() * est_camera.center_world);
  const Eigen::Affine3f truth_from_prop =
      (true_world_from_cam * est_cam_from_world * world->placed.world_from_prop.cast<double>()).cast<float>();
  // Only the spheres' box is rendered: a crop of the camera.
  cv::Rect box = cv::boundingRect(mask > 0);
  box.x = std::max(0, box.x - 2), box.y = std::max(0, box.y - 2);
  box.width = std::min(est_camera.width - box.x, box.width + 4), box.height = std::min(est_camera.height - box.y, box.height + 4);
  render::PinholeCamera crop = truth_camera;
  crop.width = box.width, crop.height = box.height;
  crop.cx -= box.x, crop.cy -= box.y;
  render::Scene truth_scene;
  truth_scene.add_prop(mesh, truth_from_prop);
  truth_scene.commit();
  cv::Mat truth(est_camera.height, est_camera.width, CV_32FC3, cv::Scalar::all(0));
  render::RenderSettings truth_settings = settings;
  render::render_image(truth_scene, crop, truth_rig, truth_settings).copyTo(truth(box));
  truth = clip01(truth);
  result.seconds = seconds_since(t);

  score_spheres(est, truth, mask, result.si_scale, result.spheres);
  // The Khan-style baseline at the same spot, scored the same way.
  score_spheres(composite_of(khan_baseline(estimate, view.photo_linear)), truth, mask, result.khan_si_scale,
                result.khan_spheres);
  result.estimate = to_display(est);
  // For the eye, the truth's rendered box pasted into the photo (the box's
  // background is the panorama itself, unquantised).
  cv::Mat truth_shown = clip01(view.photo_linear.size() == truth.size() ? view.photo_linear : truth).clone();
  truth(box).copyTo(truth_shown(box));
  result.truth = to_display(truth_shown);

  // The dominant light: the estimate's composite world a little above the
  // middle sphere's base (the spheres themselves left out), the panorama's
  // moments; both in their camera's frame.
  const auto tp = std::chrono::steady_clock::now();
  const Eigen::Vector3f probe_point =
      world->placed.world_from_prop * Eigen::Vector3f(0, static_cast<float>(o.light_probe_lift_m), 0);
  const LightMoments est_light = probe_light_moments(*world->scene, world->lights, probe_point, o.probe_face_px, o.probe_spp, o.seed);
  result.light_probe_seconds = seconds_since(tp);
  LightMoments true_light = latlong_light_moments(latlong);
  true_light.vector *= view.exposure, true_light.irradiance_up *= view.exposure, true_light.total *= view.exposure;
  result.estimate_light = rotated(est_light, est_camera.R_world_from_cam.transpose());
  result.true_light = rotated(true_light, view.camera.R_world_from_cam.transpose());
  result.direction_deg = angle_deg_or_nan(result.estimate_light.vector, result.true_light.vector);
  return result;
}

namespace {

json probe_json(const ProbeResult& p) {
  json spheres = json::array();
  for (const auto& s : p.spheres)
    spheres.push_back({{"material", s.material}, {"rmse", number_or_null(s.rmse)}, {"si_rmse", number_or_null(s.si_rmse)},
                       {"pixels", s.pixels}, {"mean_estimate", number_or_null(s.mean_estimate)},
                       {"mean_truth", number_or_null(s.mean_truth)}});
  json out = {{"placed", p.placed}};
  if (!p.placed) {
    out["why"] = p.why;
    return out;
  }
  out["at"] = {p.at.x(), p.at.y()};
  out["spheres"] = spheres;
  out["si_scale"] = number_or_null(p.si_scale);
  json khan = json::array();
  for (const auto& k : p.khan_spheres)
    khan.push_back({{"material", k.material}, {"rmse", number_or_null(k.rmse)}, {"si_rmse", number_or_null(k.si_rmse)}});
  out["khan_spheres"] = khan;
  out["khan_si_scale"] = number_or_null(p.khan_si_scale);
  out["direction_deg"] = number_or_null(p.direction_deg);
  out["estimate_light"] = moments_json(p.estimate_light);
  out["true_light"] = moments_json(p.true_light);
  out["seconds"] = p.seconds;
  out["light_probe_seconds"] = p.light_probe_seconds;
  return out;
}

}  // namespace

json run_panorama_world(const PanoramaWorldOptions& o, std::function<void(inference::InferenceOptions&)> tweak) {
  Progress progress(o.quiet);
  const auto start = std::chrono::steady_clock::now();
  // Views panorama by panorama: one that cannot be read is a row saying why.
  std::vector<PanoramaView> views;
  json rows = json::array();
  for (const std::string& name : o.panoramas.empty() ? panorama_world_names() : o.panoramas) {
    PanoramaWorldOptions one = o;
    one.panoramas = {name};
    try {
      for (auto& v : make_panorama_views(one)) views.push_back(std::move(v));
    } catch (const std::exception& e) {
      rows.push_back({{"panorama", name}, {"name", name}, {"error", e.what()}});
    }
  }
  std::string debug_dir = o.debug_dir;
  if (const char* env = std::getenv("PROPCAM_PANORAMA_WORLD_DEBUG"); debug_dir.empty() && env) debug_dir = env;
  for (const auto& v : views) {
    progress.stage("panorama world: " + v.name);
    json row = {{"panorama", v.panorama}, {"name", v.name}, {"group", v.group}, {"yaw_deg", v.yaw_deg},
                {"pitch_deg", v.pitch_deg}, {"exposure", v.exposure}, {"indoor_truth", v.indoor}};
    try {
      json loo;
      const auto tl = std::chrono::steady_clock::now();
      const inference::InferenceOptions defaults;
      inference::InferenceOptions options = leave_one_out_options(v, o, defaults, &loo);
      const double loo_seconds = seconds_since(tl);
      if (tweak) tweak(options);
      row["leave_one_out"] = loo;
      const auto ti = std::chrono::steady_clock::now();
      const inference::SceneModel est = inference::infer_scene(v.photo_linear, options);
      const double inference_seconds = seconds_since(ti);
      json stages = json::object();
      json matches = json::array();
      for (const auto& r : est.reports) {
        stages[r.stage] = stages.value(r.stage, 0.0) + r.seconds;
        if (r.stage == "ibl_ranking" && r.details.contains("matches"))
          for (const auto& m : r.details["matches"])
            if (m.contains("panorama")) matches.push_back(m["panorama"]);
      }
      // The ranked panoramas; one of the view's own group is a leak (it
      // happens with leave-one-out off: the committed ranker holds them all).
      std::set<std::string> own;
      for (const auto& m : group_members(v.group, pmndrs_dir_of(o))) own.insert(ranker_entry_name(m));
      bool self_match = false;
      for (const auto& m : matches) self_match = self_match || own.count(m.get<std::string>());
      row["ibl_matches"] = matches;
      row["ibl_self_match"] = self_match;
      row["indoor_estimate"] = est.indoor;
      row["indoor_right"] = est.indoor == v.indoor;
      row["scene_class"] = scene_class_cues(est.reports);
      row["lights"] = est.lights.size();
      const CameraErrors ce = camera_errors(est.camera(), v.camera);
      row["camera"] = {{"focal_rel", ce.focal_rel}, {"up_deg", ce.up_deg}, {"pitch_deg", ce.pitch_deg}, {"roll_deg", ce.roll_deg}};
      if (!est.light_source_mask.empty()) {
        const EmitterCounts ec = count_emitters(v.emitters, est.light_source_mask);
        row["emitters"] = {{"truth", ec.truth}, {"found", ec.found}, {"detected", ec.detected}, {"right", ec.right}};
      }
      const ProbeResult probe = score_light_probe(v, est, o);
      row["probe"] = probe_json(probe);
      if (!debug_dir.empty() && probe.placed) {
        // Photo | estimate | truth, display-referred; the scored pixels' outline on the photo.
        cv::Mat photo = to_display(clip01(v.photo_linear)), edges;
        cv::Canny(probe.mask * 80, edges, 1, 1);
        photo.setTo(cv::Scalar(1, 0, 1), edges);
        cv::Mat strip;
        cv::hconcat(std::vector<cv::Mat>{photo, probe.estimate, probe.truth}, strip);
        fs::create_directories(debug_dir);
        cv::Mat linear_strip = strip.clone();  // write_image encodes float as sRGB: undo ours
        linear_strip.forEach<cv::Vec3f>([](cv::Vec3f& c, const int*) {
          for (int k = 0; k < 3; ++k) c[k] = capture::srgb_to_linear(c[k]);
        });
        capture::write_image((fs::path(debug_dir) / (v.name + ".png")).string(), linear_strip);
      }
      row["seconds"] = {{"leave_one_out", loo_seconds}, {"inference", inference_seconds}, {"stages", stages},
                        {"probe_renders", probe.seconds}, {"light_probe", probe.light_probe_seconds}};
    } catch (const std::exception& e) {
      row["error"] = e.what();
    }
    rows.push_back(row);
  }

  // The summary.
  json summary = {{"scenes", rows.size()}};
  int classified = 0, right = 0, placed = 0;
  std::map<std::string, std::vector<double>> rmse, si, khan_si;
  std::map<std::string, int> compared, beats_khan;
  std::vector<double> dir_all, dir_in, dir_out, focal, inference_s, probe_s, light_probe_s, loo_s;
  int em_truth = 0, em_found = 0, em_detected = 0, em_right = 0;
  for (const auto& r : rows) {
    if (r.contains("indoor_estimate")) ++classified, right += r["indoor_right"].get<bool>();
    if (r.contains("camera")) focal.push_back(r["camera"]["focal_rel"].get<double>());
    if (r.contains("emitters")) {
      em_truth += r["emitters"]["truth"].get<int>(), em_found += r["emitters"]["found"].get<int>();
      em_detected += r["emitters"]["detected"].get<int>(), em_right += r["emitters"]["right"].get<int>();
    }
    if (r.contains("seconds")) {
      inference_s.push_back(r["seconds"]["inference"].get<double>());
      probe_s.push_back(r["seconds"]["probe_renders"].get<double>());
      light_probe_s.push_back(r["seconds"]["light_probe"].get<double>());
      loo_s.push_back(r["seconds"]["leave_one_out"].get<double>());
    }
    if (!r.contains("probe") || !r["probe"]["placed"].get<bool>()) continue;
    ++placed;
    for (const auto& s : r["probe"]["spheres"]) {
      const std::string m = s["material"];
      rmse[m].push_back(s["rmse"].is_number() ? s["rmse"].get<double>() : NAN);
      si[m].push_back(s["si_rmse"].is_number() ? s["si_rmse"].get<double>() : NAN);
    }
    const json& ours = r["probe"]["spheres"];
    const json& theirs = r["probe"].value("khan_spheres", json::array());
    for (size_t k = 0; k < theirs.size() && k < ours.size(); ++k) {
      const std::string m = theirs[k]["material"];
      const double a = ours[k]["si_rmse"].is_number() ? ours[k]["si_rmse"].get<double>() : NAN;
      const double b = theirs[k]["si_rmse"].is_number() ? theirs[k]["si_rmse"].get<double>() : NAN;
      khan_si[m].push_back(b);
      if (std::isfinite(a) && std::isfinite(b)) ++compared[m], beats_khan[m] += a < b ? 1 : 0;
    }
    const double d = r["probe"]["direction_deg"].is_number() ? r["probe"]["direction_deg"].get<double>() : NAN;
    dir_all.push_back(d);
    (r.value("indoor_truth", false) ? dir_in : dir_out).push_back(d);
  }
  const auto mean = [](const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x;
    return v.empty() ? NAN : s / v.size();
  };
  double loo_total = 0;
  for (double x : loo_s) loo_total += x;
  int self_matches = 0;
  for (const auto& r : rows) self_matches += r.value("ibl_self_match", false) ? 1 : 0;
  summary["ibl_self_matches"] = self_matches;
  summary["placed"] = placed;
  summary["placed_share"] = rows.empty() ? NAN : double(placed) / rows.size();
  summary["indoor_accuracy"] = number_or_null(classified ? double(right) / classified : NAN);
  json probe = json::object();
  for (const char* m : kSphereNames)
    probe[m] = {{"rmse_median", number_or_null(median(rmse[m]))},
                {"si_rmse_median", number_or_null(median(si[m]))},
                {"khan_si_rmse_median", number_or_null(median(khan_si[m]))},
                {"si_beats_khan_share", number_or_null(compared[m] ? double(beats_khan[m]) / compared[m] : NAN)}};
  summary["probe"] = probe;
  summary["direction_deg_median"] = number_or_null(median(dir_all));
  summary["direction_deg_median_indoor"] = number_or_null(median(dir_in));
  summary["direction_deg_median_outdoor"] = number_or_null(median(dir_out));
  summary["focal_rel_median"] = number_or_null(median(focal));
  summary["emitters"] = {{"truth", em_truth}, {"detected", em_detected},
                         {"recall", number_or_null(em_truth ? double(em_found) / em_truth : NAN)},
                         {"precision", number_or_null(em_detected ? double(em_right) / em_detected : NAN)}};
  summary["seconds_mean"] = {{"inference", number_or_null(mean(inference_s))},
                             {"probe_renders", number_or_null(mean(probe_s))},
                             {"light_probe", number_or_null(mean(light_probe_s))}};
  summary["leave_one_out_seconds_total"] = loo_total;
  summary["seconds_total"] = seconds_since(start);
  return {{"options", {{"views_per_panorama", o.views_per_panorama}, {"size", {o.width, o.height}},
                       {"fov_deg", o.horizontal_fov_deg}, {"pitch_deg", {o.pitch_first_deg, o.pitch_last_deg}},
                       {"spp", o.spp}, {"leave_one_out", o.leave_one_out}, {"cache_dir", o.cache_dir}}},
          {"summary", summary},
          {"scenes", rows}};
}

std::string format_panorama_world(const json& r) {
  std::ostringstream out;
  char line[400];
  const auto num = [](const json& j) { return j.is_number() ? j.get<double>() : NAN; };
  out << "Panorama world: " << r["summary"]["scenes"] << " views, leave one panorama out: "
      << (r["options"]["leave_one_out"].get<bool>() ? "yes" : "no") << "\n";
  std::snprintf(line, sizeof line, "  %-26s %6s %6s | %-15s %-15s %-15s | %6s %7s %7s\n", "view", "indoor", "call",
                "diffuse rmse/si", "rough rmse/si", "mirror rmse/si", "dir", "infer s", "probe s");
  out << line;
  for (const auto& row : r["scenes"]) {
    if (row.contains("error")) {
      out << "  " << row["name"].get<std::string>() << ": error: " << row["error"].get<std::string>() << "\n";
      continue;
    }
    const json& p = row["probe"];
    if (!p["placed"].get<bool>()) {
      std::snprintf(line, sizeof line, "  %-26s %6s %6s | not placed: %s\n", row["name"].get<std::string>().c_str(),
                    row["indoor_truth"].get<bool>() ? "in" : "out", row["indoor_estimate"].get<bool>() ? "in" : "out",
                    p["why"].get<std::string>().substr(0, 150).c_str());
      out << line;
      continue;
    }
    char cells[3][32];
    for (int k = 0; k < 3; ++k)
      std::snprintf(cells[k], sizeof cells[k], "%.3f/%.3f", num(p["spheres"][k]["rmse"]), num(p["spheres"][k]["si_rmse"]));
    std::snprintf(line, sizeof line, "  %-26s %6s %6s | %-15s %-15s %-15s | %6.1f %7.1f %7.1f\n",
                  row["name"].get<std::string>().c_str(), row["indoor_truth"].get<bool>() ? "in" : "out",
                  row["indoor_estimate"].get<bool>() ? "in" : "out", cells[0], cells[1], cells[2], num(p["direction_deg"]),
                  num(row["seconds"]["inference"]), num(row["seconds"]["probe_renders"]) + num(row["seconds"]["light_probe"]));
    out << line;
  }
  const json& s = r["summary"];
  std::snprintf(line, sizeof line,
                "  medians (placed %d of %d): diffuse %.3f / %.3f, rough metal %.3f / %.3f, mirror %.3f / %.3f (RMSE / "
                "si-RMSE); dominant light %.1f deg (indoor %.1f, outdoor %.1f); indoor/outdoor right %.2f\n",
                s["placed"].get<int>(), s["scenes"].get<int>(), num(s["probe"]["diffuse"]["rmse_median"]),
                num(s["probe"]["diffuse"]["si_rmse_median"]), num(s["probe"]["rough_metal"]["rmse_median"]),
                num(s["probe"]["rough_metal"]["si_rmse_median"]), num(s["probe"]["mirror"]["rmse_median"]),
                num(s["probe"]["mirror"]["si_rmse_median"]), num(s["direction_deg_median"]),
                num(s["direction_deg_median_indoor"]), num(s["direction_deg_median_outdoor"]), num(s["indoor_accuracy"]));
  out << line;
  std::snprintf(line, sizeof line, "  views whose IBL ranking matched their own panorama: %d\n", s.value("ibl_self_matches", 0));
  out << line;
  std::snprintf(line, sizeof line, "  seconds per view: inference %.1f, probe renders %.1f, light probe %.1f; leave-one-out training %.1f s in all; total %.1f s\n",
                num(s["seconds_mean"]["inference"]), num(s["seconds_mean"]["probe_renders"]),
                num(s["seconds_mean"]["light_probe"]), num(s["leave_one_out_seconds_total"]), num(s["seconds_total"]));
  out << line;
  return out.str();
}

}  // namespace propcam::firmware
