// Indoor/outdoor by k nearest neighbours (the paper classifies with k-NN on
// GIST): the photo's appearance descriptor (depth_transfer.h) is compared
// with labelled references; the majority of the k nearest decides. The
// references are the depth-transfer database's rendered rooms and streets
// and rectilinear views cut from real HDR panoramas (`SceneReferenceSet`,
// built by `propcam build-scene-refs`), so real photos have real neighbours.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "propcam/inference/depth_transfer.h"
#include "propcam/inference/sky.h"

namespace propcam::inference {

struct KnnSceneClass {
  bool indoor = true;
  double indoor_share = 0;  // (weighted) share of the k neighbours' votes that are indoor
  int k = 0;                // neighbours used (min(k, references))
  int real_neighbours = 0;  // of those, how many are real panorama views (not renders)
};

// One labelled reference. `group` says where it came from: kRenderedGroup
// for a generator scene, else the index of its panorama in the set's
// groups(), so an evaluation can leave a whole panorama out.
inline constexpr int kRenderedGroup = -1;
struct SceneReference {
  std::vector<float> descriptor;  // kAppearanceDescriptorLength floats
  bool indoor = true;
  int group = kRenderedGroup;
};

class SceneReferenceSet {
 public:
  // Throws std::runtime_error naming the file and the problem for a missing,
  // truncated or corrupt file, a wrong magic or version, or trailing bytes.
  static SceneReferenceSet load(const std::string& path);
  void save(const std::string& path) const;  // atomic: temporary file, then rename
  // The group of a panorama, added when new.
  int group(const std::string& name);
  // Throws std::invalid_argument for a wrong descriptor length, a non-finite
  // value or an unknown group.
  void add(SceneReference r);
  size_t size() const { return refs_.size(); }
  const SceneReference& at(size_t i) const { return refs_.at(i); }
  const std::vector<std::string>& groups() const { return groups_; }
  int find_group(const std::string& name) const;  // -2 when absent (never equal to any reference's group)

 private:
  std::vector<SceneReference> refs_;
  std::vector<std::string> groups_;
};

// The rendered rooms and streets of the depth-transfer database as references.
SceneReferenceSet rendered_references(const DepthDatabase& db);

// PROPCAM_SCENE_REFS (environment) if set, else the set committed beside the
// depth database (inference/data/scene_refs.bin).
std::string default_scene_reference_path();

struct KnnOptions {
  int k = 7;
  int exclude_group = -2;  // references of this group are skipped (leave-one-panorama-out); -2: none
  // Each vote weighted by 1 / (references of its class): the class with
  // fewer references (indoor when an indoor panorama is left out) is not
  // outvoted by its count alone.
  bool balance_classes = true;
};

// Deterministic (ties in distance go to the lower index). Throws
// std::invalid_argument for no usable reference, k < 1 or a bad photo.
KnnSceneClass classify_indoor_knn(const cv::Mat& photo_linear, const SceneReferenceSet& refs, const KnnOptions& options = {});
// The same on a descriptor already computed (benchmarks reuse one per photo).
KnnSceneClass classify_indoor_knn(const std::vector<float>& descriptor, const SceneReferenceSet& refs,
                                  const KnnOptions& options = {});
// Against the depth database's renders only (the first cut; kept for comparison).
KnnSceneClass classify_indoor_knn(const cv::Mat& photo_linear, const DepthDatabase& db, int k = 7);

// The sky rule with a learned classifier: a photo whose sky the rule sees
// and that covers at least `sky_decides_fraction` of the frame is outdoor
// unless `classifier` (scene_classifier.h) is confident it is indoor; any
// other photo is decided by the classifier when given, else by k-NN. Fills
// the "scene_class" report (method "sky", "svm_over_sky", "svm" or "knn";
// the sky fraction, the classifier's score, the k-NN indoor share and real
// neighbours).
struct CombinedSceneClassOptions {
  // Sky under 5% of the frame may be a bright wall: the classifier then
  // decides (docs/scene_class.md: best on our own world, within 1% of the
  // best on the real and Blender-rendered ones).
  double sky_decides_fraction = 0.05;
  // A larger "sky" is still a bright wall or ceiling when the classifier's
  // indoor score is at least this (docs/scene_class.md: rooms whose lit wall
  // the rule took for sky scored +0.20 to +0.57, outdoor views at most +0.07)
  // and the "sky" is under `confident_indoor_max_sky` of the frame: the
  // more of the frame is smooth and bright above the horizon, the likelier
  // it is sky (a featureless frame reads as 54% sky).
  double confident_indoor_score = 0.15;
  double confident_indoor_max_sky = 0.25;
  KnnOptions knn;
  SkyOptions sky;
};
class SceneClassifier;
bool classify_indoor_combined(const cv::Mat& photo_linear, const render::PinholeCamera& camera,
                              const SceneReferenceSet& refs, StageReport& report, SkyEstimate* sky = nullptr,
                              const CombinedSceneClassOptions& options = {}, const SceneClassifier* classifier = nullptr);

}  // namespace propcam::inference
