#include "propcam/inference/scene_class_knn.h"
#include "propcam/inference/data_dir.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <stdexcept>

#include "atomic_file.h"
#include "propcam/inference/scene_classifier.h"

namespace propcam::inference {
namespace {

// File format: magic, version, the group names, then fixed-size records.
constexpr char kMagic[8] = {'P', 'C', 'S', 'C', 'E', 'N', 'E', '\0'};
constexpr uint32_t kVersion = 1;
constexpr uint32_t kMaxReferences = 1u << 20;
constexpr uint32_t kMaxGroups = 1u << 12;
constexpr uint32_t kMaxGroupName = 256;
constexpr int kNoGroup = -2;

template <typename T>
void put(std::ostream& out, const T& v) {
  out.write(reinterpret_cast<const char*>(&v), sizeof v);
}

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw std::runtime_error("scene reference set '" + path + "' " + what);
}

template <typename T>
T get(std::istream& in, const std::string& path, const char* what) {
  T v{};
  if (!in.read(reinterpret_cast<char*>(&v), sizeof v)) fail(path, std::string("is truncated (reading ") + what + ")");
  return v;
}

void check_photo(const cv::Mat& photo_linear) {
  if (photo_linear.empty() || photo_linear.type() != CV_32FC3)
    throw std::invalid_argument("k-NN scene class: photo must be a non-empty CV_32FC3 image");
}

double squared_distance(const std::vector<float>& a, const std::vector<float>& b) {
  double sum = 0;
  for (size_t j = 0; j < a.size(); ++j) sum += (double(a[j]) - b[j]) * (double(a[j]) - b[j]);
  return sum;
}

}  // namespace

int SceneReferenceSet::find_group(const std::string& name) const {
  const auto it = std::find(groups_.begin(), groups_.end(), name);
  return it == groups_.end() ? kNoGroup : static_cast<int>(it - groups_.begin());
}

int SceneReferenceSet::group(const std::string& name) {
  if (const int g = find_group(name); g != kNoGroup) return g;
  if (name.empty() || name.size() > kMaxGroupName) throw std::invalid_argument("SceneReferenceSet: bad group name");
  groups_.push_back(name);
  return static_cast<int>(groups_.size()) - 1;
}

void SceneReferenceSet::add(SceneReference r) {
  if (r.descriptor.size() != static_cast<size_t>(kAppearanceDescriptorLength))
    throw std::invalid_argument("SceneReferenceSet::add: descriptor length differs");
  for (float v : r.descriptor)
    if (!std::isfinite(v)) throw std::invalid_argument("SceneReferenceSet::add: non-finite descriptor");
  if (r.group != kRenderedGroup && (r.group < 0 || r.group >= static_cast<int>(groups_.size())))
    throw std::invalid_argument("SceneReferenceSet::add: unknown group");
  refs_.push_back(std::move(r));
}

void SceneReferenceSet::save(const std::string& path) const {
  write_binary_atomically(path, [&](std::ostream& out) {
    out.write(kMagic, sizeof kMagic);
    put(out, kVersion);
    put(out, static_cast<uint32_t>(groups_.size()));
    for (const auto& g : groups_) {
      put(out, static_cast<uint32_t>(g.size()));
      out.write(g.data(), static_cast<std::streamsize>(g.size()));
    }
    put(out, static_cast<uint32_t>(refs_.size()));
    put(out, static_cast<uint32_t>(kAppearanceDescriptorLength));
    for (const auto& r : refs_) {
      put(out, static_cast<uint8_t>(r.indoor));
      put(out, static_cast<int32_t>(r.group));
      out.write(reinterpret_cast<const char*>(r.descriptor.data()),
                static_cast<std::streamsize>(sizeof(float) * r.descriptor.size()));
    }
  });
}

SceneReferenceSet SceneReferenceSet::load(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("no scene reference set at '" + path + "'");
  char magic[sizeof kMagic];
  if (!in.read(magic, sizeof magic) || std::memcmp(magic, kMagic, sizeof kMagic) != 0)
    throw std::runtime_error("'" + path + "' is not a PropCam scene reference set");
  const auto version = get<uint32_t>(in, path, "version");
  if (version != kVersion)
    fail(path, "has version " + std::to_string(version) + "; this build reads " + std::to_string(kVersion));
  SceneReferenceSet set;
  const auto groups = get<uint32_t>(in, path, "group count");
  if (groups > kMaxGroups) fail(path, "has a corrupt header (group count)");
  for (uint32_t g = 0; g < groups; ++g) {
    const auto length = get<uint32_t>(in, path, "group name length");
    if (length == 0 || length > kMaxGroupName) fail(path, "has a corrupt group name");
    std::string name(length, '\0');
    if (!in.read(name.data(), length)) fail(path, "is truncated (reading a group name)");
    if (set.find_group(name) != kNoGroup) fail(path, "repeats group '" + name + "'");
    set.groups_.push_back(name);
  }
  const auto count = get<uint32_t>(in, path, "count");
  const auto length = get<uint32_t>(in, path, "descriptor length");
  if (count > kMaxReferences || length != static_cast<uint32_t>(kAppearanceDescriptorLength))
    fail(path, "has a corrupt header (count or descriptor length)");
  set.refs_.reserve(count);
  for (uint32_t i = 0; i < count; ++i) {
    SceneReference r;
    const auto indoor = get<uint8_t>(in, path, "class");
    if (indoor > 1) fail(path, "has a corrupt class in reference " + std::to_string(i));
    r.indoor = indoor != 0;
    r.group = get<int32_t>(in, path, "group");
    if (r.group != kRenderedGroup && (r.group < 0 || r.group >= static_cast<int>(groups)))
      fail(path, "has an unknown group in reference " + std::to_string(i));
    r.descriptor.resize(length);
    if (!in.read(reinterpret_cast<char*>(r.descriptor.data()), sizeof(float) * length))
      fail(path, "is truncated (reading a descriptor)");
    for (float v : r.descriptor)
      if (!std::isfinite(v)) fail(path, "has a non-finite descriptor in reference " + std::to_string(i));
    set.refs_.push_back(std::move(r));
  }
  if (in.peek() != std::char_traits<char>::eof()) fail(path, "has trailing bytes");
  return set;
}

SceneReferenceSet rendered_references(const DepthDatabase& db) {
  SceneReferenceSet set;
  for (size_t i = 0; i < db.size(); ++i) set.add({db.at(i).descriptor, db.at(i).indoor, kRenderedGroup});
  return set;
}

std::string default_scene_reference_path() {
  if (const char* env = std::getenv("PROPCAM_SCENE_REFS"); env && *env) return env;
  // Shipped beside the depth database, from which its renders come.
  return data_file("inference/scene_refs.bin").string();
}

KnnSceneClass classify_indoor_knn(const std::vector<float>& query, const SceneReferenceSet& refs, const KnnOptions& options) {
  if (options.k < 1) throw std::invalid_argument("k-NN scene class: k must be at least 1");
  if (query.size() != static_cast<size_t>(kAppearanceDescriptorLength))
    throw std::invalid_argument("k-NN scene class: descriptor length differs");
  std::vector<size_t> order;
  std::vector<double> distance(refs.size());
  for (size_t i = 0; i < refs.size(); ++i) {
    if (refs.at(i).group == options.exclude_group) continue;
    distance[i] = squared_distance(refs.at(i).descriptor, query);
    order.push_back(i);
  }
  if (order.empty()) throw std::invalid_argument("k-NN scene class: no references");
  const int used = static_cast<int>(std::min<size_t>(static_cast<size_t>(options.k), order.size()));
  std::partial_sort(order.begin(), order.begin() + used, order.end(), [&](size_t a, size_t b) {
    return distance[a] < distance[b] || (distance[a] == distance[b] && a < b);
  });
  size_t indoor_refs = 0;
  for (size_t i : order) indoor_refs += refs.at(i).indoor ? 1 : 0;
  const size_t outdoor_refs = order.size() - indoor_refs;
  const auto vote = [&](bool indoor) {
    if (!options.balance_classes) return 1.0;
    return 1.0 / static_cast<double>(std::max<size_t>(1, indoor ? indoor_refs : outdoor_refs));
  };
  double indoor_votes = 0, all_votes = 0;
  int real = 0;
  for (int i = 0; i < used; ++i) {
    const SceneReference& r = refs.at(order[i]);
    indoor_votes += r.indoor ? vote(true) : 0;
    all_votes += vote(r.indoor);
    real += r.group != kRenderedGroup ? 1 : 0;
  }
  KnnSceneClass out;
  out.k = used;
  out.real_neighbours = real;
  out.indoor_share = indoor_votes / all_votes;
  // An even split can tie: indoor then wins, the class that asks nothing of the sky.
  out.indoor = 2 * indoor_votes >= all_votes;
  return out;
}

KnnSceneClass classify_indoor_knn(const cv::Mat& photo_linear, const SceneReferenceSet& refs, const KnnOptions& options) {
  check_photo(photo_linear);
  if (refs.size() == 0) throw std::invalid_argument("k-NN scene class: no references");
  if (options.k < 1) throw std::invalid_argument("k-NN scene class: k must be at least 1");
  return classify_indoor_knn(appearance_descriptor(photo_linear), refs, options);
}

KnnSceneClass classify_indoor_knn(const cv::Mat& photo_linear, const DepthDatabase& db, int k) {
  if (db.size() == 0) throw std::invalid_argument("k-NN scene class: empty database");
  // The first cut, unchanged: a plain majority.
  return classify_indoor_knn(photo_linear, rendered_references(db), KnnOptions{k, kNoGroup, false});
}

bool classify_indoor_combined(const cv::Mat& photo_linear, const render::PinholeCamera& camera,
                              const SceneReferenceSet& refs, StageReport& report, SkyEstimate* sky_out,
                              const CombinedSceneClassOptions& options, const SceneClassifier* classifier) {
  const auto start = std::chrono::steady_clock::now();
  SkyEstimate sky;
  const bool sky_says_indoor = classify_indoor(photo_linear, camera, report, &sky, options.sky);
  report.details["sky_rule"] = sky_says_indoor ? "indoor" : "outdoor";
  // Both learned cues run on every photo (milliseconds) so the report shows them.
  const std::vector<float> descriptor = appearance_descriptor(photo_linear);
  const KnnSceneClass knn = classify_indoor_knn(descriptor, refs, options.knn);
  report.details["knn_indoor_share"] = knn.indoor_share;
  report.details["knn_k"] = knn.k;
  report.details["knn_real_neighbours"] = knn.real_neighbours;
  report.details["references"] = refs.size();
  double score = 0;
  if (classifier) report.details["svm_indoor_score"] = score = classifier->indoor_score(descriptor);
  bool indoor = sky_says_indoor;
  const auto short_number = [](double v) { return std::to_string(v).substr(0, 5); };
  const std::string sky_cover = std::to_string(static_cast<int>(std::lround(100 * sky.fraction))) + "%";
  const bool sky_seen = !sky_says_indoor && sky.fraction >= options.sky_decides_fraction;
  if (sky_seen && classifier && score >= options.confident_indoor_score &&
      sky.fraction < options.confident_indoor_max_sky) {
    indoor = true;
    report.details["method"] = "svm_over_sky";
    report.why = "\"sky\" covers " + sky_cover + " of the frame, but SVM: indoor (score " + short_number(score) +
                 " >= " + short_number(options.confident_indoor_score) + "): a lit wall or ceiling";
  } else if (sky_seen) {
    report.details["method"] = "sky";
    report.why = "sky covers " + sky_cover + " of the frame: outdoor";
  } else if (classifier) {
    // A tie goes indoor, the class that asks nothing of the sky.
    indoor = score >= 0;
    report.details["method"] = "svm";
    report.why = std::string("SVM: ") + (indoor ? "indoor" : "outdoor") + " (score " + short_number(score) + ")";
  } else {
    indoor = knn.indoor;
    report.details["method"] = "knn";
    report.why = std::string("k-NN: ") + (indoor ? "indoor" : "outdoor") + " (indoor share " + short_number(knn.indoor_share) + ")";
  }
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (sky_out) *sky_out = std::move(sky);
  return indoor;
}

}  // namespace propcam::inference
