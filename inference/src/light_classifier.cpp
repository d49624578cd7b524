#include "propcam/inference/light_classifier.h"
#include "propcam/inference/data_dir.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <opencv2/ml.hpp>
#include <opencv2/ximgproc.hpp>
#include <stdexcept>
#include <unistd.h>

#include "atomic_file.h"
#include "propcam/capture/image_file.h"
#include "propcam/render/panorama.h"
#include "luminance.h"


namespace propcam::inference {
namespace {

// --- Features ---
// Filters per scale: 9 Laws masks and 4 oriented Sobel edges on Y, a local
// average on Cb and on Cr, and Y itself (brightness is what a light is).
constexpr int kFilters = 16;
// Per filter: energy (mean r^2) and kurtosis-like mean r^4; plus the share of
// clipped pixels and the brightest Y.
constexpr int kOwnFeatures = 2 * kFilters + 2;
constexpr int kNeighbours = 4;  // top, left, bottom, right
constexpr int kScales = 2;      // 100% and 50%
constexpr int kFeatureCount = 1 + kScales * (1 + kNeighbours) * kOwnFeatures;
// A channel at or above this (display-referred, 0..1) is clipped.
constexpr float kClippedEncoded = 0.98f;
// SLIC's compactness (OpenCV's SLICO adapts it; fixed iterations keep the time bounded).
constexpr int kSlicIterations = 10;
// The smallest photo the features are computed for.
constexpr int kMinSide = 8;

// Laws' 1D masks: level, edge, spot.
const float kL3[3] = {1.f, 2.f, 1.f};
const float kE3[3] = {-1.f, 0.f, 1.f};
const float kS3[3] = {-1.f, 2.f, -1.f};

cv::Mat separable(const cv::Mat& src, const float* row, const float* col) {
  cv::Mat out;
  cv::sepFilter2D(src, out, CV_32F, cv::Mat(1, 3, CV_32F, const_cast<float*>(row)),
                  cv::Mat(3, 1, CV_32F, const_cast<float*>(col)), {-1, -1}, 0, cv::BORDER_REFLECT);
  return out;
}

// The 16 filter responses of an encoded YCbCr image (CV_32FC3, Y in 0..1).
std::vector<cv::Mat> filter_bank(const cv::Mat& ycc) {
  std::vector<cv::Mat> ch;
  cv::split(ycc, ch);
  const cv::Mat& y = ch[0];
  std::vector<cv::Mat> r;
  const float* masks[3] = {kL3, kE3, kS3};
  for (const float* a : masks)
    for (const float* b : masks) r.push_back(separable(y, a, b) / 16.f);
  cv::Mat gx, gy;
  cv::Sobel(y, gx, CV_32F, 1, 0, 3, 0.25, 0, cv::BORDER_REFLECT);
  cv::Sobel(y, gy, CV_32F, 0, 1, 3, 0.25, 0, cv::BORDER_REFLECT);
  r.push_back(gx);
  r.push_back(gy);
  r.push_back((gx + gy) * 0.70710678f);
  r.push_back((gx - gy) * 0.70710678f);
  r.push_back(separable(ch[2], kL3, kL3) / 16.f);  // Cb (OpenCV orders Y, Cr, Cb)
  r.push_back(separable(ch[1], kL3, kL3) / 16.f);  // Cr
  r.push_back(y.clone());
  return r;
}

// The photo as a camera file holds it: sRGB-encoded, clipped to 0..1.
cv::Mat encoded_rgb(const cv::Mat& linear) {
  cv::Mat out(linear.size(), CV_32FC3);
  for (int yy = 0; yy < linear.rows; ++yy) {
    const cv::Vec3f* in = linear.ptr<cv::Vec3f>(yy);
    cv::Vec3f* o = out.ptr<cv::Vec3f>(yy);
    for (int x = 0; x < linear.cols; ++x)
      for (int c = 0; c < 3; ++c) {
        const float v = std::isfinite(in[x][c]) ? in[x][c] : 0.f;
        o[x][c] = std::clamp(capture::linear_to_srgb(v), 0.f, 1.f);
      }
  }
  return out;
}

// Per superpixel, the own features at one scale: responses (at the work
// size) aggregated over its pixels.
cv::Mat own_features(const std::vector<cv::Mat>& responses, const cv::Mat& encoded, const cv::Mat& labels, int count) {
  cv::Mat f = cv::Mat::zeros(count, kOwnFeatures, CV_64F);
  std::vector<int> pixels(count, 0);
  for (int y = 0; y < labels.rows; ++y)
    for (int x = 0; x < labels.cols; ++x) {
      const int l = labels.at<int>(y, x);
      if (l < 0 || l >= count) continue;
      ++pixels[l];
      double* row = f.ptr<double>(l);
      for (int k = 0; k < kFilters; ++k) {
        const double v = responses[k].at<float>(y, x);
        const double v2 = v * v;
        row[2 * k] += v2;
        row[2 * k + 1] += v2 * v2;
      }
      const cv::Vec3f e = encoded.at<cv::Vec3f>(y, x);
      if (std::max({e[0], e[1], e[2]}) >= kClippedEncoded) row[2 * kFilters] += 1.0;
      const double luma = responses[kFilters - 1].at<float>(y, x);
      row[2 * kFilters + 1] = std::max(row[2 * kFilters + 1], luma);
    }
  for (int l = 0; l < count; ++l) {
    if (pixels[l] == 0) continue;
    double* row = f.ptr<double>(l);
    for (int k = 0; k < 2 * kFilters + 1; ++k) row[k] /= pixels[l];
  }
  cv::Mat out;
  f.convertTo(out, CV_32F);
  return out;
}

// Each superpixel's neighbour in four directions: the superpixel found one
// region size away from its centroid (itself at the border).
std::vector<std::array<int, kNeighbours>> neighbours(const cv::Mat& labels, int count, int step) {
  std::vector<double> sx(count, 0), sy(count, 0);
  std::vector<int> n(count, 0);
  for (int y = 0; y < labels.rows; ++y)
    for (int x = 0; x < labels.cols; ++x) {
      const int l = labels.at<int>(y, x);
      if (l < 0 || l >= count) continue;
      sx[l] += x, sy[l] += y, ++n[l];
    }
  std::vector<std::array<int, kNeighbours>> out(count);
  const int dx[kNeighbours] = {0, -1, 0, 1}, dy[kNeighbours] = {-1, 0, 1, 0};
  for (int l = 0; l < count; ++l) {
    const int cx = n[l] ? static_cast<int>(sx[l] / n[l]) : 0, cy = n[l] ? static_cast<int>(sy[l] / n[l]) : 0;
    for (int d = 0; d < kNeighbours; ++d) {
      const int x = std::clamp(cx + dx[d] * step, 0, labels.cols - 1), y = std::clamp(cy + dy[d] * step, 0, labels.rows - 1);
      const int m = labels.at<int>(y, x);
      out[l][d] = m >= 0 && m < count ? m : l;
    }
  }
  return out;
}

cv::Mat work_image(const cv::Mat& photo_linear, int work_width) {
  const int w = std::max(kMinSide, std::min(work_width, photo_linear.cols));
  const int h = std::max(kMinSide, static_cast<int>(std::lround(static_cast<double>(w) * photo_linear.rows / photo_linear.cols)));
  cv::Mat small;
  cv::resize(photo_linear, small, {w, h}, 0, 0, cv::INTER_AREA);
  return small;
}

}  // namespace

int light_feature_count() { return kFeatureCount; }

SuperpixelFeatures superpixel_features(const cv::Mat& photo_linear, const LightClassifierOptions& options) {
  if (photo_linear.empty() || photo_linear.type() != CV_32FC3 || photo_linear.cols < kMinSide || photo_linear.rows < kMinSide)
    throw std::invalid_argument("light classifier: needs a CV_32FC3 photo of at least 8x8");
  const cv::Mat encoded = encoded_rgb(work_image(photo_linear, options.work_width));
  cv::Mat ycc;
  cv::cvtColor(encoded, ycc, cv::COLOR_RGB2YCrCb);
  SuperpixelFeatures out;
  {
    cv::Mat lab8, encoded8;
    encoded.convertTo(encoded8, CV_8UC3, 255.0);
    cv::cvtColor(encoded8, lab8, cv::COLOR_RGB2Lab);
    auto slic = cv::ximgproc::createSuperpixelSLIC(lab8, cv::ximgproc::SLICO, std::max(4, options.superpixel_px));
    slic->iterate(kSlicIterations);
    slic->getLabels(out.labels);
    out.count = slic->getNumberOfSuperpixels();
  }
  const auto near = neighbours(out.labels, out.count, std::max(4, options.superpixel_px));
  out.features = cv::Mat::zeros(out.count, kFeatureCount, CV_32F);
  // Height in the image (0 top, 1 bottom).
  {
    std::vector<double> sy(out.count, 0);
    std::vector<int> n(out.count, 0);
    for (int y = 0; y < out.labels.rows; ++y)
      for (int x = 0; x < out.labels.cols; ++x) {
        const int l = out.labels.at<int>(y, x);
        if (l >= 0 && l < out.count) sy[l] += y, ++n[l];
      }
    for (int l = 0; l < out.count; ++l)
      out.features.at<float>(l, 0) = n[l] ? static_cast<float>(sy[l] / n[l] / std::max(1, out.labels.rows - 1)) : 0.f;
  }
  for (int scale = 0; scale < kScales; ++scale) {
    std::vector<cv::Mat> responses;
    if (scale == 0) {
      responses = filter_bank(ycc);
    } else {
      // Half resolution, responses brought back to the work size so that the
      // same superpixels aggregate them.
      cv::Mat half;
      cv::resize(ycc, half, {}, 0.5, 0.5, cv::INTER_AREA);
      for (const cv::Mat& r : filter_bank(half)) {
        cv::Mat up;
        cv::resize(r, up, ycc.size(), 0, 0, cv::INTER_LINEAR);
        responses.push_back(up);
      }
    }
    const cv::Mat own = own_features(responses, encoded, out.labels, out.count);
    const int base = 1 + scale * (1 + kNeighbours) * kOwnFeatures;
    for (int l = 0; l < out.count; ++l) {
      own.row(l).copyTo(out.features.row(l).colRange(base, base + kOwnFeatures));
      for (int d = 0; d < kNeighbours; ++d) {
        const int c = base + (1 + d) * kOwnFeatures;
        own.row(near[l][d]).copyTo(out.features.row(l).colRange(c, c + kOwnFeatures));
      }
    }
  }
  cv::patchNaNs(out.features, 0.0);
  return out;
}

LightClassifier::LightClassifier() = default;
LightClassifier::~LightClassifier() = default;
LightClassifier::LightClassifier(LightClassifier&&) noexcept = default;
LightClassifier& LightClassifier::operator=(LightClassifier&&) noexcept = default;

LightClassifier LightClassifier::train(const cv::Mat& features, const cv::Mat& labels, int trees, int depth) {
  if (features.empty() || features.rows != labels.rows || features.cols != kFeatureCount || labels.type() != CV_32S)
    throw std::invalid_argument("light classifier: features and labels do not match");
  const int positives = cv::countNonZero(labels);
  if (positives == 0 || positives == labels.rows)
    throw std::invalid_argument("light classifier: training needs both sources and non-sources");
  cv::theRNG().state = 0x5eed;  // the forest's bootstrap and feature draws: deterministic
  LightClassifier c;
  c.forest_ = cv::ml::RTrees::create();
  c.forest_->setMaxDepth(depth);
  c.forest_->setMinSampleCount(4);
  c.forest_->setCalculateVarImportance(false);
  c.forest_->setActiveVarCount(static_cast<int>(std::sqrt(static_cast<double>(kFeatureCount))));
  c.forest_->setTermCriteria({cv::TermCriteria::MAX_ITER, std::max(1, trees), 0});
  // Sources are rare: weigh the classes equally.
  const float ratio = static_cast<float>(labels.rows - positives) / positives;
  c.forest_->setPriors(cv::Mat(cv::Matx12f(1.f, ratio)));
  c.forest_->train(cv::ml::TrainData::create(features, cv::ml::ROW_SAMPLE, labels));
  return c;
}

LightClassifier LightClassifier::load(const std::string& path) {
  if (!std::filesystem::exists(path)) throw std::runtime_error("light classifier '" + path + "' does not exist");
  LightClassifier c;
  try {
    c.forest_ = cv::Algorithm::load<cv::ml::RTrees>(path);
  } catch (const cv::Exception& e) {
    throw std::runtime_error("light classifier '" + path + "' is not a forest: " + e.what());
  }
  if (!c.forest_ || !c.forest_->isTrained() || c.forest_->getVarCount() != kFeatureCount)
    throw std::runtime_error("light classifier '" + path + "' is not a trained forest over " +
                             std::to_string(kFeatureCount) + " features");
  return c;
}

void LightClassifier::save(const std::string& path) const {
  if (!forest_) throw std::runtime_error("light classifier: nothing to save");
  write_atomically(path, [&](const std::string& tmp) { forest_->save(tmp); });
}

std::vector<float> LightClassifier::scores(const cv::Mat& features) const {
  std::vector<float> out(features.rows, 0.f);
  if (!forest_ || features.empty()) return out;
  cv::Mat votes;
  forest_->getVotes(features, votes, 0);
  // Row 0 holds the class labels; then per sample the votes per class.
  int source_col = -1;
  for (int c = 0; c < votes.cols; ++c)
    if (votes.at<int>(0, c) == 1) source_col = c;
  if (source_col < 0) return out;
  for (int r = 0; r < features.rows; ++r) {
    int total = 0;
    for (int c = 0; c < votes.cols; ++c) total += votes.at<int>(r + 1, c);
    out[r] = total > 0 ? static_cast<float>(votes.at<int>(r + 1, source_col)) / total : 0.f;
  }
  return out;
}

cv::Mat LightClassifier::source_mask(const cv::Mat& photo_linear, const LightClassifierOptions& options,
                                     StageReport* report) const {
  const auto start = std::chrono::steady_clock::now();
  const SuperpixelFeatures f = superpixel_features(photo_linear, options);
  const std::vector<float> s = scores(f.features);
  cv::Mat small(f.labels.size(), CV_8U, cv::Scalar(0));
  int sources = 0;
  std::vector<char> on(f.count, 0);
  for (int l = 0; l < f.count; ++l) sources += on[l] = s[l] >= options.threshold;
  for (int y = 0; y < small.rows; ++y)
    for (int x = 0; x < small.cols; ++x) {
      const int l = f.labels.at<int>(y, x);
      if (l >= 0 && l < f.count && on[l]) small.at<uint8_t>(y, x) = 255;
    }
  cv::Mat mask;
  cv::resize(small, mask, photo_linear.size(), 0, 0, cv::INTER_NEAREST);
  if (report) {
    report->details["superpixels"] = f.count;
    report->details["source_superpixels"] = sources;
    report->details["classifier_seconds"] =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  return mask;
}

std::string default_light_classifier_path() {
  if (const char* env = std::getenv("PROPCAM_LIGHT_CLASSIFIER"); env && *env) return env;
  return data_file("inference/light_classifier.yml.gz").string();
}

std::vector<LabelledView> panorama_views(const cv::Mat& latlong, int views_per_turn, const std::vector<double>& pitches_deg,
                                         double horizontal_fov_deg, int width, int height, double source_over_white) {
  std::vector<LabelledView> out;
  for (double pitch : pitches_deg)
    for (int v = 0; v < views_per_turn; ++v) {
      render::ViewSpec spec;
      spec.width = width;
      spec.height = height;
      spec.horizontal_fov_deg = horizontal_fov_deg;
      spec.yaw_deg = 360.0 * v / views_per_turn;
      spec.pitch_deg = pitch;
      cv::Mat linear = render::rectilinear_view(latlong, render::view_camera(spec));
      const double scale = render::auto_expose(linear);
      (void)scale;
      LabelledView view;
      // Sources: radiance well above what the exposure can record (white = 1).
      view.source_mask = luminance_image(linear) >= source_over_white;
      view.photo_linear = capture::srgb8_to_linear(capture::linear_to_srgb8(linear));
      out.push_back(std::move(view));
    }
  return out;
}

LabelledFeatures labelled_features(const std::vector<LabelledView>& views, const LightClassifierOptions& options) {
  LabelledFeatures out;
  std::vector<int> labels;
  for (const auto& v : views) {
    const SuperpixelFeatures f = superpixel_features(v.photo_linear, options);
    cv::Mat mask;
    cv::resize(v.source_mask, mask, f.labels.size(), 0, 0, cv::INTER_NEAREST);
    std::vector<int> on(f.count, 0), n(f.count, 0);
    for (int y = 0; y < mask.rows; ++y)
      for (int x = 0; x < mask.cols; ++x) {
        const int l = f.labels.at<int>(y, x);
        if (l < 0 || l >= f.count) continue;
        ++n[l];
        on[l] += mask.at<uint8_t>(y, x) != 0;
      }
    out.features.push_back(f.features);
    for (int l = 0; l < f.count; ++l) labels.push_back(n[l] > 0 && 2 * on[l] >= n[l] ? 1 : 0);
  }
  out.labels = cv::Mat(labels, true).reshape(1, static_cast<int>(labels.size()));
  return out;
}

cv::Mat threshold_source_mask(const cv::Mat& photo_linear, double fraction_of_max, double min_luminance) {
  const cv::Mat lum = luminance_image(photo_linear);
  double max_lum = 0;
  cv::minMaxLoc(lum, nullptr, &max_lum);
  return lum >= std::max(min_luminance, fraction_of_max * max_lum);
}

}  // namespace propcam::inference
