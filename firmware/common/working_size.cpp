#include "common/working_size.h"

#include "propcam/capture/image_file.h"
#include "propcam/render/path_tracer.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace propcam::firmware {
namespace {

// Added to both sides of the ratio composite / photo, so black pixels give a
// bounded ratio (linear units: a tenth of the darkest sRGB step above 0).
constexpr float kRatioFloor = 3e-5f;
// A bounce of light onto a nearly black pixel cannot multiply it more than this.
constexpr float kMaxRatio = 64.f;
// Below this coverage the prop's colour is not solved from the pixel (its
// noise divided by a small share shows as a coloured fringe); it is taken
// from covered neighbours instead.
constexpr float kMinCoverageForColour = 0.5f;
// Upsampling reads one working pixel around each full one; the fills reach
// this many pixels beyond what is known.
constexpr int kFillReach = 2;
// The prop's colour is filled this many working pixels beyond its coverage.
constexpr int kColourFillReach = 8;
// A blur below this many full-size pixels is not worth a pass over the coverage.
constexpr double kMinBlurSigma = 0.3;

// Gives every unknown pixel of `values` (weight 0) the mean of its known
// 3x3 neighbours, growing by one pixel per pass, for at most `passes` passes.
void fill_unknown(cv::Mat& values, cv::Mat& known, int passes) {
  for (int pass = 0; pass < passes; ++pass) {
    const int known_count = cv::countNonZero(known);
    if (known_count == 0 || known_count == static_cast<int>(known.total())) return;
    cv::Mat weighted, weight;
    cv::Mat known3;
    cv::merge(std::vector<cv::Mat>{known, known, known}, known3);
    cv::boxFilter(values.mul(known3), weighted, -1, cv::Size(3, 3), cv::Point(-1, -1), false, cv::BORDER_REPLICATE | cv::BORDER_ISOLATED);
    cv::boxFilter(known, weight, -1, cv::Size(3, 3), cv::Point(-1, -1), false, cv::BORDER_REPLICATE | cv::BORDER_ISOLATED);
    cv::Mat grown = known.clone();
    for (int y = 0; y < values.rows; ++y) {
      const float* k = known.ptr<float>(y);
      const float* w = weight.ptr<float>(y);
      const auto* sum = weighted.ptr<cv::Vec3f>(y);
      auto* v = values.ptr<cv::Vec3f>(y);
      float* g = grown.ptr<float>(y);
      for (int x = 0; x < values.cols; ++x)
        if (k[x] == 0.f && w[x] > 0.f) {
          v[x] = sum[x] / w[x];
          g[x] = 1.f;
        }
    }
    known = grown;
  }
}

}  // namespace

void check_photo_pixels(const std::string& path, cv::Size size) {
  const double pixels = static_cast<double>(size.width) * size.height;
  if (pixels > static_cast<double>(kMaxPhotoPixels))
    throw std::invalid_argument("the photo '" + path + "' is " + std::to_string(size.width) + "x" +
                                std::to_string(size.height) + " (" + std::to_string(static_cast<long>(pixels / 1e6)) +
                                " megapixels); PropCam takes photos of at most " +
                                std::to_string(kMaxPhotoPixels / 1'000'000) + " megapixels");
}

cv::Size working_size(cv::Size full, long max_pixels) {
  if (full.width <= 0 || full.height <= 0) throw std::invalid_argument("working_size: the photo has no pixels");
  if (max_pixels <= 0) throw std::invalid_argument("working_size: the pixel budget must be positive");
  const double pixels = static_cast<double>(full.width) * full.height;
  if (pixels <= static_cast<double>(max_pixels)) return full;
  const double scale = std::sqrt(static_cast<double>(max_pixels) / pixels);
  cv::Size size(std::max(1, static_cast<int>(std::floor(full.width * scale))),
                std::max(1, static_cast<int>(std::floor(full.height * scale))));
  // A side held at one pixel gives the budget to the other.
  if (static_cast<long>(size.width) * size.height > max_pixels) {
    if (size.height == 1) size.width = static_cast<int>(std::min<long>(max_pixels, full.width));
    else size.height = static_cast<int>(std::min<long>(max_pixels, full.height));
  }
  return size;
}

cv::Mat reduce_to(const cv::Mat& photo, cv::Size size) {
  if (photo.size() == size) return photo.clone();
  cv::Mat out;
  cv::resize(photo, out, size, 0, 0, cv::INTER_AREA);
  return out;
}

bool same_view_reduced(cv::Size full, cv::Size working) {
  if (working.width > full.width || working.height > full.height) return false;
  const double expected_height = static_cast<double>(working.width) * full.height / full.width;
  return std::abs(expected_height - working.height) <= 1.0;
}

WorkingPhoto load_working_photo(const std::string& path, long budget, cv::Size forced) {
  namespace fs = std::filesystem;
  WorkingPhoto photo;
  photo.path = path;
  photo.full_size = capture::photo_file_size(path);
  check_photo_pixels(path, photo.full_size);
  const cv::Size size = forced.width > 0 ? forced : working_size(photo.full_size, budget);
  if (size.width > photo.full_size.width || size.height > photo.full_size.height)
    throw std::invalid_argument("the photo '" + path + "' is " + std::to_string(photo.full_size.width) + "x" +
                                std::to_string(photo.full_size.height) + ", smaller than the " +
                                std::to_string(size.width) + "x" + std::to_string(size.height) + " it is needed at");
  photo.working = size == photo.full_size ? capture::load_photo_linear(path) : capture::load_photo_reduced(path, size);
  if (size == photo.full_size && photo.working.size() != size)
    throw std::runtime_error("the photo '" + path + "' changed while it was being read");
  photo.file_bytes = fs::file_size(path);
  photo.file_time = fs::last_write_time(path);
  return photo;
}

void write_full_size_composite(const WorkingPhoto& photo, const std::string& out_path,
                               const FullSizeDelivery& delivery, double gamma) {
  namespace fs = std::filesystem;
  constexpr int kBandRows = 64;
  const std::string changed = "the photo '" + photo.path + "' changed while it was being composited; nothing was written";
  if (fs::file_size(photo.path) != photo.file_bytes || fs::last_write_time(photo.path) != photo.file_time)
    throw std::runtime_error(changed);
  capture::PhotoRowReader in(photo.path);
  if (in.size() != photo.full_size) throw std::runtime_error(changed);
  capture::ImageRowWriter out(out_path, photo.full_size);
  for (int y = 0; y < photo.full_size.height; y += kBandRows) {
    const int rows = std::min(kBandRows, photo.full_size.height - y);
    cv::Mat band = capture::srgb_linear_to_response_linear(in.read(y, rows), gamma);
    delivery.apply(band, y);
    out.write(capture::response_linear_to_srgb_linear(band, gamma));
  }
  out.finish();
}

FullSizeDelivery::FullSizeDelivery(const cv::Mat& working_photo, const cv::Mat& working_composite,
                                   const cv::Mat& coverage, cv::Size full_size)
    : full_size_(full_size), coverage_(coverage.clone()) {
  if (working_photo.type() != CV_32FC3 || working_composite.type() != CV_32FC3 ||
      coverage.type() != CV_32F || working_photo.size() != working_composite.size() ||
      coverage.size() != working_photo.size())
    throw std::invalid_argument("FullSizeDelivery: CV_32FC3 photo and composite, CV_32F coverage, all one size");
  if (full_size.width < working_photo.cols || full_size.height < working_photo.rows)
    throw std::invalid_argument("FullSizeDelivery: the full size is smaller than the working size");
  const cv::Size ws = working_photo.size();

  // 1. What the prop left alone: no coverage and the composite equal to the photo.
  cv::Mat& untouched = untouched_;
  untouched.create(ws, CV_8U);
  // 2. Outside the prop: the change as a ratio; under it, the ratio of its surroundings.
  cv::Mat& ratio = ratio_;
  ratio.create(ws, CV_32FC3);
  cv::Mat ratio_known(ws, CV_32F);
  for (int y = 0; y < ws.height; ++y) {
    const auto* p = working_photo.ptr<cv::Vec3f>(y);
    const auto* c = working_composite.ptr<cv::Vec3f>(y);
    const float* m = coverage.ptr<float>(y);
    auto* r = ratio.ptr<cv::Vec3f>(y);
    float* known = ratio_known.ptr<float>(y);
    uchar* u = untouched.ptr<uchar>(y);
    for (int x = 0; x < ws.width; ++x) {
      u[x] = m[x] == 0.f && c[x] == p[x];
      known[x] = m[x] == 0.f ? 1.f : 0.f;
      for (int k = 0; k < 3; ++k)
        r[x][k] = m[x] == 0.f ? std::min(kMaxRatio, (std::max(0.f, c[x][k]) + kRatioFloor) / (p[x][k] + kRatioFloor))
                              : 1.f;
    }
  }
  // Only around the prop is anything unknown: fill there, from the ring of
  // known pixels just outside it, until the whole region is known.
  cv::Mat covered = coverage > 0.f;
  const cv::Rect around = (cv::boundingRect(covered) + cv::Size(2 * kFillReach, 2 * kFillReach) -
                           cv::Point(kFillReach, kFillReach)) &
                          cv::Rect(0, 0, ws.width, ws.height);
  if (!around.empty()) {
    cv::Mat ratio_around = ratio(around), known_around = ratio_known(around);
    fill_unknown(ratio_around, known_around, std::max(around.width, around.height));
  }

  // 3. The prop's own colour: composite = (1 - c) photo ratio + c colour.
  cv::Mat& colour = colour_;
  colour.create(ws, CV_32FC3);
  colour.setTo(cv::Scalar::all(0));
  cv::Mat colour_known(ws, CV_32F, cv::Scalar(0));
  for (int y = 0; y < ws.height; ++y) {
    const auto* p = working_photo.ptr<cv::Vec3f>(y);
    const auto* c = working_composite.ptr<cv::Vec3f>(y);
    const auto* r = ratio.ptr<cv::Vec3f>(y);
    const float* m = coverage.ptr<float>(y);
    auto* col = colour.ptr<cv::Vec3f>(y);
    float* known = colour_known.ptr<float>(y);
    for (int x = 0; x < ws.width; ++x) {
      if (m[x] < kMinCoverageForColour) continue;
      for (int k = 0; k < 3; ++k)
        col[x][k] = std::max(0.f, (c[x][k] - (1.f - m[x]) * p[x][k] * r[x][k]) / m[x]);
      known[x] = 1.f;
    }
  }
  // Further out for the colour: a sharp coverage blurred by the photo's
  // blur reaches beyond what the working render covered.
  const cv::Rect colour_around = (cv::boundingRect(covered) + cv::Size(2 * kColourFillReach, 2 * kColourFillReach) -
                                  cv::Point(kColourFillReach, kColourFillReach)) &
                                 cv::Rect(0, 0, ws.width, ws.height);
  if (!colour_around.empty()) {
    cv::Mat values = colour(colour_around), known = colour_known(colour_around);
    fill_unknown(values, known, 2 * kColourFillReach);
  }

  // 4. The bilinear taps of every full column and row.
  const auto taps = [](int full, int working) {
    std::vector<Taps> out(full);
    const double scale = static_cast<double>(working) / full;
    for (int i = 0; i < full; ++i) {
      const double u = std::clamp((i + 0.5) * scale - 0.5, 0.0, working - 1.0);
      const int lo = static_cast<int>(std::floor(u));
      out[i] = {lo, std::min(lo + 1, working - 1), static_cast<float>(u - lo)};
    }
    return out;
  };
  xs_ = taps(full_size.width, ws.width);
  ys_ = taps(full_size.height, ws.height);
}

int sharp_coverage_rays_per_side(long region_pixels) {
  if (region_pixels <= 0 || region_pixels > kMaxSharpCoveragePixels) return 0;
  for (int n = kSharpCoverageRaysPerSide; n > 1; --n)
    if (static_cast<long long>(n) * n * region_pixels <= kMaxSharpCoverageRays) return n;
  return 1;
}

SharpCoverage full_size_prop_coverage(const render::Scene& world, const render::PinholeCamera& working_camera,
                                      const cv::Mat& working_coverage, cv::Size full_size,
                                      double blur_sigma_working_px) {
  const auto start = std::chrono::steady_clock::now();
  SharpCoverage sharp;
  const cv::Rect seen = cv::boundingRect(working_coverage > 0.f);
  if (seen.empty()) return sharp;
  const double sx = static_cast<double>(full_size.width) / working_coverage.cols;
  const double sy = static_cast<double>(full_size.height) / working_coverage.rows;
  const double blur_sigma = std::max(0.0, blur_sigma_working_px) * sx;
  // A working pixel beyond what it saw (a thin part its samples missed) and
  // room for the blur's tail, within the reach of the prop's filled colour.
  const int margin = static_cast<int>(std::ceil(std::min(sx + 3.0 * blur_sigma, (kColourFillReach - 1) * sx))) + 1;
  const cv::Rect scaled(static_cast<int>(std::floor(seen.x * sx)), static_cast<int>(std::floor(seen.y * sy)),
                        static_cast<int>(std::ceil(seen.width * sx)), static_cast<int>(std::ceil(seen.height * sy)));
  sharp.region = (scaled + cv::Size(2 * margin, 2 * margin) - cv::Point(margin, margin)) &
                 cv::Rect(0, 0, full_size.width, full_size.height);
  const int rays_per_side = sharp_coverage_rays_per_side(static_cast<long>(sharp.region.area()));
  if (rays_per_side == 0) return {};
  const render::PinholeCamera full_camera = working_camera.resized(full_size.width, full_size.height);
  sharp.coverage = render::render_prop_coverage(world, full_camera, sharp.region, rays_per_side);
  sharp.rays_per_side = rays_per_side;
  if (blur_sigma > kMinBlurSigma) cv::GaussianBlur(sharp.coverage, sharp.coverage, cv::Size(), blur_sigma);
  sharp.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return sharp;
}

void FullSizeDelivery::use_sharp_coverage(SharpCoverage sharp) {
  if (!sharp.empty() && (sharp.coverage.type() != CV_32F || sharp.coverage.size() != sharp.region.size() ||
                         (sharp.region & cv::Rect(0, 0, full_size_.width, full_size_.height)) != sharp.region))
    throw std::invalid_argument("FullSizeDelivery: a sharp coverage is CV_32F, its region's size, within the full size");
  sharp_ = std::move(sharp);
}

void FullSizeDelivery::apply(cv::Mat& rows, int first_row) const {
  if (rows.type() != CV_32FC3 || rows.cols != full_size_.width || first_row < 0 ||
      first_row + rows.rows > full_size_.height)
    throw std::invalid_argument("FullSizeDelivery::apply: CV_32FC3 rows of the full width, within its height");
  for (int y = 0; y < rows.rows; ++y) {
    const Taps ty = ys_[first_row + y];
    const uchar* u0 = untouched_.ptr<uchar>(ty.lo);
    const uchar* u1 = untouched_.ptr<uchar>(ty.hi);
    auto* out = rows.ptr<cv::Vec3f>(y);
    for (int x = 0; x < rows.cols; ++x) {
      const Taps tx = xs_[x];
      if (u0[tx.lo] && u0[tx.hi] && u1[tx.lo] && u1[tx.hi]) continue;
      const std::array<cv::Point, 4> at{cv::Point(tx.lo, ty.lo), cv::Point(tx.hi, ty.lo), cv::Point(tx.lo, ty.hi),
                                        cv::Point(tx.hi, ty.hi)};
      const std::array<float, 4> w{(1 - tx.t) * (1 - ty.t), tx.t * (1 - ty.t), (1 - tx.t) * ty.t, tx.t * ty.t};
      float m = 0.f;
      cv::Vec3f r(0, 0, 0), col(0, 0, 0);
      for (int i = 0; i < 4; ++i) {
        m += w[i] * coverage_.at<float>(at[i]);
        r += w[i] * ratio_.at<cv::Vec3f>(at[i]);
        col += w[i] * colour_.at<cv::Vec3f>(at[i]);
      }
      if (!sharp_.empty() && sharp_.region.contains({x, first_row + y}))
        m = sharp_.coverage.at<float>(first_row + y - sharp_.region.y, x - sharp_.region.x);
      for (int k = 0; k < 3; ++k) out[x][k] = m * col[k] + (1.f - m) * out[x][k] * r[k];
    }
  }
}

void deliver_at_full_size(cv::Mat& full_photo, const cv::Mat& working_photo, const cv::Mat& working_composite,
                          const cv::Mat& coverage) {
  FullSizeDelivery(working_photo, working_composite, coverage, full_photo.size()).apply(full_photo, 0);
}

}  // namespace propcam::firmware
