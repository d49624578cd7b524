#include "propcam/render/relight.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace propcam::render {
namespace {

// Where the empty scene is darker than this, the relighting ratio is 1:
// no light to scale.
constexpr float kMinEmptySceneLuminance = 1e-4f;
// A photo is never brightened more than this by relighting (noise in dim
// low-resolution layers would otherwise explode).
constexpr float kMaxRelightRatio = 16.f;

float scale_of(const LightScales& scales, size_t i) {
  const float s = i < scales.size() ? scales[i] : 1.f;
  if (!std::isfinite(s) || s < 0.f) throw std::invalid_argument("relight: light scales must be finite and >= 0");
  return s;
}

void check_layers(const cv::Mat& photo, const LightLayers& layers) {
  if (photo.type() != CV_32FC3 || layers.coverage.size() != photo.size() || layers.coverage.type() != CV_32F)
    throw std::invalid_argument("relight: photo and layers must match (CV_32FC3 photo, CV_32F coverage)");
  for (const auto& c : layers.change)
    if (c.size() != photo.size() || c.type() != CV_32FC3) throw std::invalid_argument("relight: a layer has the wrong size");
}

cv::Mat scaled_change(const LightLayers& layers, const LightScales& scales) {
  cv::Mat sum(layers.coverage.size(), CV_32FC3, cv::Scalar::all(0));
  for (size_t i = 0; i < layers.change.size(); ++i) cv::scaleAdd(layers.change[i], scale_of(scales, i), sum, sum);
  return sum;
}

cv::Mat combine(const cv::Mat& base, const cv::Mat& coverage, const cv::Mat& change) {
  cv::Mat out(base.size(), CV_32FC3);
  for (int y = 0; y < out.rows; ++y)
    for (int x = 0; x < out.cols; ++x) {
      const float m = coverage.at<float>(y, x);
      const cv::Vec3f b = base.at<cv::Vec3f>(y, x), c = change.at<cv::Vec3f>(y, x);
      for (int k = 0; k < 3; ++k) out.at<cv::Vec3f>(y, x)[k] = std::max(0.f, (1.f - m) * b[k] + c[k]);
    }
  return out;
}

}  // namespace

cv::Mat relight_prop(const cv::Mat& photo_linear, const LightLayers& layers, const LightScales& scales) {
  check_layers(photo_linear, layers);
  return combine(photo_linear, layers.coverage, scaled_change(layers, scales));
}

SceneLightLayers render_scene_light_layers(const Scene& scene, const PinholeCamera& camera, const LightRig& lights,
                                           int width, const RenderSettings& settings) {
  SceneLightLayers out;
  width = std::clamp(width, 1, camera.width);
  const int height = std::max(1, static_cast<int>(std::lround(static_cast<double>(width) * camera.height / camera.width)));
  const PinholeCamera small = camera.resized(width, height);
  // The empty scene is the background world: props are not traced.
  out.empty_scene = render_background_light_images(scene, small, lights, settings);
  return out;
}

cv::Mat relight_scene(const cv::Mat& photo_linear, const LightLayers& layers, const SceneLightLayers& scene_layers,
                      const LightScales& scales) {
  check_layers(photo_linear, layers);
  if (scene_layers.empty_scene.empty()) return relight_prop(photo_linear, layers, scales);
  const cv::Size low = scene_layers.empty_scene.front().size();
  cv::Mat original(low, CV_32F, cv::Scalar(0)), relit(low, CV_32F, cv::Scalar(0));
  for (size_t i = 0; i < scene_layers.empty_scene.size(); ++i) {
    cv::Mat lum;
    cv::transform(scene_layers.empty_scene[i], lum, cv::Matx13f(0.2126f, 0.7152f, 0.0722f));
    original += lum;
    cv::scaleAdd(lum, scale_of(scales, i), relit, relit);
  }
  cv::Mat ratio(low, CV_32F);
  for (int y = 0; y < low.height; ++y)
    for (int x = 0; x < low.width; ++x) {
      const float o = original.at<float>(y, x);
      ratio.at<float>(y, x) = o > kMinEmptySceneLuminance ? std::min(relit.at<float>(y, x) / o, kMaxRelightRatio) : 1.f;
    }
  // Light varies smoothly; the photo keeps its detail.
  cv::GaussianBlur(ratio, ratio, {0, 0}, 1.0);
  cv::resize(ratio, ratio, photo_linear.size(), 0, 0, cv::INTER_LINEAR);
  cv::Mat base(photo_linear.size(), CV_32FC3);
  for (int y = 0; y < base.rows; ++y)
    for (int x = 0; x < base.cols; ++x) base.at<cv::Vec3f>(y, x) = photo_linear.at<cv::Vec3f>(y, x) * ratio.at<float>(y, x);
  return combine(base, layers.coverage, scaled_change(layers, scales));
}

}  // namespace propcam::render
