#include "worlds/world_metrics.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "propcam/inference/lighting.h"

namespace propcam::firmware {
namespace {

constexpr double kRadToDeg = 180.0 / std::numbers::pi;
// SSIM's constants for a dynamic range of 1 (Wang et al. 2004).
constexpr double kSsimC1 = 0.01 * 0.01, kSsimC2 = 0.03 * 0.03;
constexpr double kSsimSigmaPx = 1.5;
constexpr int kSsimWindowPx = 11;
// Below this the truth of an LMSE window or a depth pixel carries nothing to scale by.
constexpr double kTinyEnergy = 1e-12;

cv::Mat luma(const cv::Mat& rgb) {
  cv::Mat out;
  cv::transform(rgb, out, cv::Matx13f(0.2126f, 0.7152f, 0.0722f));
  cv::patchNaNs(out, 0.0);
  return out;
}

cv::Mat mask_or_all(const cv::Mat& mask, const cv::Size& size) {
  return mask.empty() ? cv::Mat(size, CV_8U, cv::Scalar(255)) : mask;
}

}  // namespace

double ssim_in_mask(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
  const cv::Mat m = mask_or_all(mask, a.size());
  if (a.empty() || cv::countNonZero(m) == 0) return std::nan("");
  cv::Mat x, y;
  luma(a).convertTo(x, CV_64F);
  luma(b).convertTo(y, CV_64F);
  const cv::Size window(kSsimWindowPx, kSsimWindowPx);
  const auto blur = [&](const cv::Mat& in) {
    cv::Mat out;
    cv::GaussianBlur(in, out, window, kSsimSigmaPx, kSsimSigmaPx, cv::BORDER_REFLECT);
    return out;
  };
  const cv::Mat mx = blur(x), my = blur(y);
  const cv::Mat sxx = blur(x.mul(x)) - mx.mul(mx), syy = blur(y.mul(y)) - my.mul(my), sxy = blur(x.mul(y)) - mx.mul(my);
  const cv::Mat num = (2 * mx.mul(my) + kSsimC1).mul(2 * sxy + kSsimC2);
  const cv::Mat den = (mx.mul(mx) + my.mul(my) + kSsimC1).mul(sxx + syy + kSsimC2);
  cv::Mat map;
  cv::divide(num, den, map);
  return cv::mean(map, m)[0];
}

double depth_abs_rel_median_scaled(const cv::Mat& estimate, const cv::Mat& truth, const cv::Mat& valid,
                                   double max_depth_m) {
  if (estimate.empty() || truth.empty() || estimate.size() != truth.size()) return std::nan("");
  const cv::Mat m = mask_or_all(valid, truth.size());
  std::vector<double> ratios;
  std::vector<cv::Point> pixels;
  for (int y = 0; y < truth.rows; ++y)
    for (int x = 0; x < truth.cols; ++x) {
      const double e = estimate.at<float>(y, x), t = truth.at<float>(y, x);
      if (!m.at<uint8_t>(y, x) || !(e > 0 && e < max_depth_m) || !(t > kTinyEnergy && t < max_depth_m)) continue;
      ratios.push_back(t / e);
      pixels.push_back({x, y});
    }
  if (ratios.empty()) return std::nan("");
  std::vector<double> sorted = ratios;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double scale = sorted[sorted.size() / 2];
  double sum = 0;
  for (const cv::Point& p : pixels) {
    const double t = truth.at<float>(p);
    sum += std::abs(scale * estimate.at<float>(p) - t) / t;
  }
  return sum / pixels.size();
}

double albedo_lmse(const cv::Mat& estimate, const cv::Mat& truth, const cv::Mat& valid, int window) {
  if (estimate.empty() || truth.empty() || estimate.size() != truth.size() || window < 2) return std::nan("");
  const cv::Mat m = mask_or_all(valid, truth.size());
  // Window origins every window/2, the last flush with the far edge.
  const auto origins = [&](int extent) {
    std::vector<int> out;
    const int last = std::max(0, extent - window);
    for (int o = 0; o < last; o += std::max(1, window / 2)) out.push_back(o);
    out.push_back(last);
    return out;
  };
  double error = 0, energy = 0;
  for (const int y0 : origins(truth.rows))
    for (const int x0 : origins(truth.cols)) {
      const cv::Rect r(x0, y0, std::min(window, truth.cols - x0), std::min(window, truth.rows - y0));
      for (int c = 0; c < 3; ++c) {
        double et = 0, ee = 0, tt = 0;
        for (int y = r.y; y < r.y + r.height; ++y)
          for (int x = r.x; x < r.x + r.width; ++x) {
            if (!m.at<uint8_t>(y, x)) continue;
            const double e = estimate.at<cv::Vec3f>(y, x)[c], t = truth.at<cv::Vec3f>(y, x)[c];
            if (!std::isfinite(e) || !std::isfinite(t)) continue;
            et += e * t, ee += e * e, tt += t * t;
          }
        const double alpha = ee > kTinyEnergy ? et / ee : 0.0;
        error += std::max(0.0, tt - 2 * alpha * et + alpha * alpha * ee);
        energy += tt;
      }
    }
  return energy > kTinyEnergy ? error / energy : std::nan("");
}

CameraErrors camera_errors(const render::PinholeCamera& est, const render::PinholeCamera& truth) {
  CameraErrors e;
  e.focal_rel = std::abs(est.fx / truth.fx - 1.0);
  // World up (Y) in each camera's frame.
  const Eigen::Vector3d up_est = est.R_world_from_cam.transpose() * Eigen::Vector3d::UnitY();
  const Eigen::Vector3d up_true = truth.R_world_from_cam.transpose() * Eigen::Vector3d::UnitY();
  e.up_deg = angle_between_deg(up_est, up_true);
  // Camera y points down: pitch (up positive) from the up vector's z, roll from its x.
  const auto pitch = [](const Eigen::Vector3d& up) { return std::asin(std::clamp(up.z(), -1.0, 1.0)) * kRadToDeg; };
  const auto roll = [](const Eigen::Vector3d& up) { return std::atan2(up.x(), -up.y()) * kRadToDeg; };
  e.pitch_deg = std::abs(pitch(up_est) - pitch(up_true));
  e.roll_deg = std::abs(roll(up_est) - roll(up_true));
  const double h_true = truth.center_world.y(), h_est = est.center_world.y();
  e.height_rel = std::abs(h_true) > kTinyEnergy ? std::abs(h_est / h_true - 1.0) : std::nan("");
  return e;
}

EmitterCounts count_emitters(const cv::Mat& truth, const cv::Mat& estimate, double min_fraction, double min_cover,
                             int tolerance_px) {
  EmitterCounts out;
  if (truth.empty()) return out;
  const cv::Mat est = estimate.empty() ? cv::Mat::zeros(truth.size(), CV_8U) : (estimate > 0);
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(truth > 0, labels, stats, centroids, 8, CV_32S);
  const double min_area = min_fraction * truth.total();
  for (int i = 1; i < n; ++i) {
    const int area = stats.at<int>(i, cv::CC_STAT_AREA);
    if (area < min_area) continue;
    ++out.truth;
    const int covered = cv::countNonZero((labels == i) & est);
    if (covered >= min_cover * area) ++out.found;
  }
  // Every emitter, and the counted ones alone, grown by the tolerance.
  cv::Mat counted = cv::Mat::zeros(truth.size(), CV_8U);
  for (int i = 1; i < n; ++i)
    if (stats.at<int>(i, cv::CC_STAT_AREA) >= min_area) counted |= labels == i;
  cv::Mat any = truth > 0;
  if (tolerance_px > 0) {
    const cv::Mat disc = cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * tolerance_px + 1, 2 * tolerance_px + 1});
    cv::dilate(any, any, disc);
    cv::dilate(counted, counted, disc);
  }
  cv::Mat est_labels, est_stats, est_centroids;
  const int k = cv::connectedComponentsWithStats(est, est_labels, est_stats, est_centroids, 8, CV_32S);
  for (int i = 1; i < k; ++i) {
    const int area = est_stats.at<int>(i, cv::CC_STAT_AREA);
    const cv::Mat component = est_labels == i;
    if (2 * cv::countNonZero(component & any) < area) {
      ++out.detected;  // mostly off every emitter: wrong
    } else if (cv::countNonZero(component & counted) > 0) {
      ++out.detected, ++out.right;
    }  // else: on small emitters only, which count neither way
  }
  return out;
}

double angle_between_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  if (!a.allFinite() || !b.allFinite() || !(a.norm() > 0) || !(b.norm() > 0)) return 180.0;
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * kRadToDeg;
}

inference::SceneModel khan_baseline(const inference::SceneModel& estimate, const cv::Mat& photo_linear) {
  inference::SceneModel khan = estimate;
  inference::LightSource env;
  env.type = inference::LightSource::Type::Ibl;
  env.environment = inference::environment_from_photo(photo_linear, estimate.camera(), kKhanEnvironmentWidth);
  khan.lights = {env};
  khan.enclosure = {};  // the baseline's room is open: the wrapped photo lights it from every side
  khan.gamma = 2.2;
  return khan;
}

nlohmann::json scene_class_cues(const std::vector<inference::StageReport>& reports) {
  nlohmann::json cues = nlohmann::json::object();
  for (const auto& r : reports) {
    if (r.stage == "scene_class") cues.update(r.details);
    if (r.stage == "orientation_map")
      for (const char* key : {"ceiling_fraction", "floor_fraction"}) cues[key] = r.details.value(key, nlohmann::json());
  }
  return cues;
}

}  // namespace propcam::firmware
