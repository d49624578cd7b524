// Visible light sources (Karsch et al. 2014, "light classifier"): SLIC
// superpixels of the photo as the camera encoded it, per superpixel its
// height in the image and the energy and kurtosis of a filter bank in YCbCr
// (Make3D's features: Laws masks and oriented edges on Y, local averages on
// Cb and Cr, plus brightness and clipping), concatenated with those of its
// four neighbours, at two scales; a random forest (OpenCV ml) says which
// superpixels emit. The training data replaces the paper's hand-labelled
// SUN360 views with views of HDR panoramas whose emitters are labelled from
// radiance (see inference/README.md, "Visible light sources").
#pragma once

#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "propcam/inference/scene_model.h"

namespace cv::ml {
class RTrees;
}

namespace propcam::inference {

struct LightClassifierOptions {
  int work_width = 320;    // features are computed at this width (the second scale at half of it)
  int superpixel_px = 12;  // SLIC region size at the work width
  double threshold = 0.5;  // share of the forest's votes that makes a superpixel a source
};

struct SuperpixelFeatures {
  cv::Mat labels;         // CV_32S superpixel index per pixel, at the work size
  cv::Mat features;       // CV_32F, one row per superpixel
  int count = 0;
};

// Number of features per superpixel.
int light_feature_count();

// `photo_linear` CV_32FC3 (any size >= 8x8); deterministic; always finite.
SuperpixelFeatures superpixel_features(const cv::Mat& photo_linear, const LightClassifierOptions& options = {});

class LightClassifier {
 public:
  LightClassifier();
  ~LightClassifier();
  LightClassifier(LightClassifier&&) noexcept;
  LightClassifier& operator=(LightClassifier&&) noexcept;

  // Trains on rows of `features` with 0/1 `labels` (CV_32S, one per row);
  // deterministic for the same data. Throws std::invalid_argument on empty or
  // mismatched data or a single class.
  static LightClassifier train(const cv::Mat& features, const cv::Mat& labels, int trees = 60, int depth = 12);
  // Throws std::runtime_error naming the file when it is missing, not a
  // forest, or has the wrong feature count.
  static LightClassifier load(const std::string& path);
  void save(const std::string& path) const;  // atomic (temporary name, rename)

  // Per superpixel: the share of trees that vote "source" (0..1).
  std::vector<float> scores(const cv::Mat& features) const;
  // CV_8U mask at the photo's size, 255 on pixels of superpixels scored at
  // least options.threshold.
  cv::Mat source_mask(const cv::Mat& photo_linear, const LightClassifierOptions& options, StageReport* report = nullptr) const;

 private:
  cv::Ptr<cv::ml::RTrees> forest_;
};

// Env PROPCAM_LIGHT_CLASSIFIER, else the model committed in inference/data.
std::string default_light_classifier_path();

// Training and evaluation views: a panorama (linear HDR latlong) cut into
// rectilinear views exposed as a camera would (97th luminance percentile to
// 0.9, clipped, 8-bit sRGB), each pixel labelled a source when its radiance
// is at least `source_over_white` times the exposure's clipping level.
struct LabelledView {
  cv::Mat photo_linear;  // CV_32FC3, as loaded from the 8-bit file
  cv::Mat source_mask;   // CV_8U, 255 on emitting pixels
};
std::vector<LabelledView> panorama_views(const cv::Mat& latlong, int views_per_turn, const std::vector<double>& pitches_deg,
                                         double horizontal_fov_deg, int width, int height, double source_over_white = 4.0);

// Superpixel features of the views, each labelled a source when at least
// half its pixels are.
struct LabelledFeatures {
  cv::Mat features;  // CV_32F
  cv::Mat labels;    // CV_32S, 0/1
};
LabelledFeatures labelled_features(const std::vector<LabelledView>& views, const LightClassifierOptions& options = {});

// The threshold detector the classifier replaces (the first cut): luminance
// of the linear photo at least max(min_luminance, fraction x its maximum).
cv::Mat threshold_source_mask(const cv::Mat& photo_linear, double fraction_of_max = 0.8, double min_luminance = 0.6);

}  // namespace propcam::inference
