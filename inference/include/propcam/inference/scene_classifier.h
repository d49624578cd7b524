// Indoor/outdoor by a support vector machine on the appearance descriptor
// (depth_transfer.h), trained on the labelled references of a
// SceneReferenceSet (renders, real panorama views, the Blender world's tune
// photos). Replaces the k-NN vote as the scene-class stage's default: on
// the union of worlds, grouped cross-validation puts it at 0.90 on the
// Blender photos and 0.75 on panorama views, against 0.69 and 0.72 for
// k-NN (docs/scene_class.md).
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "propcam/inference/scene_class_knn.h"

namespace cv::ml {
class SVM;
}

namespace propcam::inference {

struct SceneClassifierOptions {
  double c = 1.0;  // soft margin; cross-validated over 0.3..10 (docs/scene_class.md)
};

class SceneClassifier {
 public:
  SceneClassifier();
  ~SceneClassifier();
  SceneClassifier(SceneClassifier&&) noexcept;
  SceneClassifier& operator=(SceneClassifier&&) noexcept;

  // An RBF SVM on standardised descriptors, classes weighted equally,
  // gamma = 1 / (length * variance) as scikit-learn's "scale". References of
  // `exclude_group` are left out (leave-one-panorama-out). Deterministic.
  // Throws std::invalid_argument unless both classes are present.
  static SceneClassifier train(const SceneReferenceSet& refs, int exclude_group = -2,
                               const SceneClassifierOptions& options = {});
  // Throws std::runtime_error naming the file for a missing or broken model.
  static SceneClassifier load(const std::string& path);
  void save(const std::string& path) const;  // atomic

  // The SVM's decision value: positive means indoor. Finite for any finite
  // descriptor; throws std::invalid_argument for a wrong length.
  double indoor_score(const std::vector<float>& descriptor) const;

 private:
  cv::Ptr<cv::ml::SVM> svm_;
  std::vector<float> mean_, inv_std_;
  double sign_ = 1.0;  // OpenCV's raw output for a two-class SVM can point either way
};

// PROPCAM_SCENE_CLASSIFIER (environment) if set, else the model committed
// beside the references it was trained on (inference/data/scene_classifier.yml.gz,
// written by `propcam build-scene-refs`).
std::string default_scene_classifier_path();

}  // namespace propcam::inference
