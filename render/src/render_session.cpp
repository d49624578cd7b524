#include "propcam/render/render_session.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <mutex>
#include <stdexcept>
#include <thread>

namespace propcam::render {
namespace {

using Clock = std::chrono::steady_clock;

// Tiles darker than this are judged against it, so noise on a black wall
// does not read as an infinite relative error.
constexpr double kMinReferenceLuminance = 0.05;

// Passes double a tile's samples up to this count and then add half of them:
// early snapshots come fast, and later passes overshoot the sample count
// at which a tile reaches its target by at most 50% instead of 100%.
constexpr int kDoublingSamplesLimit = 16;

int samples_in_next_pass(int samples_so_far) {
  if (samples_so_far < kDoublingSamplesLimit) return std::max(1, samples_so_far);
  return samples_so_far / 2;
}

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Variance of a pixel's mean change luminance (its squared standard error).
double mean_change_variance(const DifferentialPixel& p) {
  const double n = std::max(1, p.samples);
  const Eigen::Vector3f& s = p.change_sum;
  const double mean = (0.2126 * s.x() + 0.7152 * s.y() + 0.0722 * s.z()) / n;
  const double variance = std::max(0.0, p.change_luminance_sq_sum / n - mean * mean);
  return n > 1 ? variance / (n - 1) : variance;
}

// Some sample of the pixel was changed by the prop.
bool touched_by_prop(const DifferentialPixel& p) { return p.untouched < p.samples; }

}  // namespace

RenderSession::RenderSession(const Scene& scene, const PinholeCamera& camera, const LightRig& lights,
                             const cv::Mat& photo_linear, const Eigen::AlignedBox3f& prop_bounds,
                             const SessionSettings& settings)
    : scene_(scene), camera_(camera), lights_(lights), photo_(photo_linear), settings_(settings) {
  if (camera.width <= 0 || camera.height <= 0) throw std::invalid_argument("render session: camera has no pixels");
  if (photo_linear.type() != CV_32FC3 || photo_linear.cols != camera.width || photo_linear.rows != camera.height)
    throw std::invalid_argument("render session: the photo must be CV_32FC3 at the camera's size");
  if (settings.max_samples_per_pixel <= 0) throw std::invalid_argument("render session: max samples must be positive");
  if (settings.render.max_bounces < 0) throw std::invalid_argument("render session: max_bounces must be >= 0");
  const auto start = Clock::now();
  if (settings.cull_tiles) {
    reach_ = estimate_prop_reach(scene, camera, lights, prop_bounds, settings.reach);
  } else {
    reach_.affected = cv::Mat(camera.height, camera.width, CV_8U, cv::Scalar(255));
  }
  const int tile = std::max(1, settings.render.tile_size);
  for (int y = 0; y < camera.height; y += tile)
    for (int x = 0; x < camera.width; x += tile) {
      TileStatus t;
      t.rect = cv::Rect(x, y, std::min(tile, camera.width - x), std::min(tile, camera.height - y));
      t.affected = cv::countNonZero(reach_.affected(t.rect)) > 0;
      t.done = !t.affected;
      tiles_.push_back(t);
    }
  // Each tile's pixels are made when it is first traced (by the thread that
  // traces it): zeroing a whole frame of them up front took as long as the
  // first pass (75 ms of 27 MB at 640x480), and culled tiles never need any.
  tile_pixels_.resize(tiles_.size());
  total_seconds_ = seconds_since(start);
}

bool RenderSession::finished() const {
  return std::all_of(tiles_.begin(), tiles_.end(), [](const TileStatus& t) { return t.done; });
}

void RenderSession::render_tile(int index, int first_sample, int count) {
  TileStatus& tile = tiles_[index];
  const auto start = Clock::now();
  // Accumulate into a copy: a tile is either fully updated or untouched, so a
  // cancelled pass leaves a consistent state.
  std::vector<DifferentialPixel> local = tile_pixels_[index];
  local.resize(tile.rect.area());
  accumulate_differential_pixels(scene_, camera_, lights_, settings_.render, tile.rect, first_sample, count, local);
  // Error: RMS over pixels of the standard error of the per-sample change
  // luminance, relative to the tile's brightness in the photo.
  double se2 = 0.0, brightness = 0.0;
  size_t i = 0;
  for (int y = tile.rect.y; y < tile.rect.br().y; ++y)
    for (int x = tile.rect.x; x < tile.rect.br().x; ++x, ++i) {
      se2 += mean_change_variance(local[i]);
      const cv::Vec3f c = photo_.at<cv::Vec3f>(y, x);
      brightness += 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    }
  const double pixels = std::max<size_t>(1, local.size());
  tile_pixels_[index] = std::move(local);
  tile.samples = first_sample + count;
  tile.relative_error = std::sqrt(se2 / pixels) / std::max(brightness / pixels, kMinReferenceLuminance);
  tile.seconds += seconds_since(start);
  const bool converged = settings_.target_relative_error > 0 &&
                         tile.samples >= std::max(2, settings_.min_samples_to_converge) &&
                         tile.relative_error <= settings_.target_relative_error;
  tile.done = converged || tile.samples >= settings_.max_samples_per_pixel;
}

PassReport RenderSession::run_pass(const std::atomic<bool>* cancel) {
  const auto start = Clock::now();
  PassReport report;
  std::vector<int> work;
  for (int i = 0; i < static_cast<int>(tiles_.size()); ++i)
    if (!tiles_[i].done) work.push_back(i);
  std::atomic<int> next{0}, traced{0};
  std::atomic<long long> pixel_samples{0};
  std::atomic<bool> stopped{false};
  auto worker = [&] {
    for (int k; (k = next.fetch_add(1)) < static_cast<int>(work.size());) {
      if (cancel && cancel->load()) {
        stopped = true;
        return;
      }
      TileStatus& t = tiles_[work[k]];
      const int count = samples_to_add(t);
      render_tile(work[k], t.samples, count);
      ++traced;
      pixel_samples += static_cast<long long>(t.rect.area()) * count;
    }
  };
  int threads = settings_.render.threads > 0 ? settings_.render.threads : static_cast<int>(std::thread::hardware_concurrency());
  threads = std::clamp(threads, 1, std::max(1, static_cast<int>(work.size())));
  {
    std::vector<std::jthread> pool;
    for (int i = 1; i < threads; ++i) pool.emplace_back(worker);
    worker();
  }
  ++passes_;
  report.pass = passes_;
  report.cancelled = stopped;
  report.tiles_traced = traced;
  for (const auto& t : tiles_) {
    report.tiles_culled += !t.affected;
    report.tiles_done += t.done;
    report.max_samples = std::max(report.max_samples, t.samples);
    if (t.affected) report.max_relative_error = std::max(report.max_relative_error, t.relative_error);
  }
  report.pass_seconds = seconds_since(start);
  total_seconds_ += report.pass_seconds;
  report.total_seconds = total_seconds_;
  last_pass_seconds_ = report.pass_seconds;
  last_pass_pixel_samples_ = pixel_samples;
  return report;
}

int RenderSession::samples_to_add(const TileStatus& t) const {
  // 0 -> 1 -> 2 -> 4 -> 8 -> 16 -> 24 -> 36 ..., capped at the limit.
  return std::min(samples_in_next_pass(t.samples), settings_.max_samples_per_pixel - t.samples);
}

double RenderSession::predicted_next_pass_seconds() const {
  if (passes_ == 0 || last_pass_pixel_samples_ <= 0) return 0.0;
  long long next_pixel_samples = 0;
  for (const TileStatus& t : tiles_)
    if (!t.done) next_pixel_samples += static_cast<long long>(t.rect.area()) * samples_to_add(t);
  return last_pass_seconds_ * static_cast<double>(next_pixel_samples) / static_cast<double>(last_pass_pixel_samples_);
}

DifferentialRender RenderSession::differential() const {
  DifferentialRender out;
  out.coverage = cv::Mat(camera_.height, camera_.width, CV_32F, cv::Scalar(0));
  out.change = cv::Mat(camera_.height, camera_.width, CV_32FC3, cv::Scalar::all(0));
  for_each_traced_pixel([&](int x, int y, const DifferentialPixel& p) {
    const float inv = 1.f / static_cast<float>(p.samples);
    out.coverage.at<float>(y, x) = p.prop_samples * inv;
    out.change.at<cv::Vec3f>(y, x) = cv::Vec3f(p.change_sum.x(), p.change_sum.y(), p.change_sum.z()) * inv;
  });
  out.stats = stats();
  return out;
}

LightLayers RenderSession::light_layers() const {
  LightLayers out;
  out.coverage = differential().coverage;
  if (!settings_.render.light_layers) return out;
  const size_t n = static_cast<size_t>(lights_.count()) + 1;  // rig lights, then emissive surfaces
  for (size_t i = 0; i < n; ++i) out.change.emplace_back(camera_.height, camera_.width, CV_32FC3, cv::Scalar::all(0));
  for_each_traced_pixel([&](int x, int y, const DifferentialPixel& p) {
    const float inv = 1.f / static_cast<float>(p.samples);
    for (size_t i = 0; i < n && i < p.change_sum_per_light.size(); ++i) {
      const Eigen::Vector3f& c = p.change_sum_per_light[i];
      out.change[i].at<cv::Vec3f>(y, x) = cv::Vec3f(c.x(), c.y(), c.z()) * inv;
    }
  });
  return out;
}

namespace {

// What the denoiser needs beside the mean change: the means over the odd and
// the even samples, the variance of the full mean's luminance, and which
// pixels the prop changed.
struct SessionBuffers {
  cv::Mat odd, even, variance, touched;
};

// `for_each_pixel(f)` calls f(x, y, pixel) for every traced pixel.
template <typename ForEachPixel>
SessionBuffers session_buffers(const ForEachPixel& for_each_pixel, int width, int height) {
  SessionBuffers b;
  b.variance = cv::Mat(height, width, CV_32F, cv::Scalar(0));
  b.odd = cv::Mat(height, width, CV_32FC3, cv::Scalar::all(0));
  b.even = cv::Mat(height, width, CV_32FC3, cv::Scalar::all(0));
  b.touched = cv::Mat(height, width, CV_8U, cv::Scalar(0));
  for_each_pixel([&](int x, int y, const DifferentialPixel& p) {
    const auto to_vec = [](const Eigen::Vector3f& v) { return cv::Vec3f(v.x(), v.y(), v.z()); };
    const int odd = p.samples / 2, even = p.samples - odd;
    if (odd > 0) b.odd.at<cv::Vec3f>(y, x) = to_vec(p.change_sum_odd) / static_cast<float>(odd);
    b.even.at<cv::Vec3f>(y, x) = to_vec(p.change_sum - p.change_sum_odd) / static_cast<float>(even);
    b.variance.at<float>(y, x) = static_cast<float>(mean_change_variance(p));
    b.touched.at<uint8_t>(y, x) = touched_by_prop(p) ? 255 : 0;
  });
  return b;
}

}  // namespace

DifferentialRender RenderSession::denoised(DenoiseReport* report) const {
  const auto start = Clock::now();
  DifferentialRender out = differential();
  const auto in_filter_range = [&](const TileStatus& t) {
    return t.affected && t.samples >= 2 && t.samples <= settings_.denoise_options.max_samples;
  };
  if (std::none_of(tiles_.begin(), tiles_.end(), in_filter_range)) {
    if (report) *report = DenoiseReport{0, 0, seconds_since(start)};
    return out;
  }
  const SessionBuffers b =
      session_buffers([&](const auto& f) { for_each_traced_pixel(f); }, camera_.width, camera_.height);
  std::vector<cv::Rect> judged;
  for (const TileStatus& t : tiles_)
    if (in_filter_range(t) && cv::countNonZero(b.touched(t.rect)) > 0) judged.push_back(t.rect);
  DenoiseReport r;
  r.tiles_judged = static_cast<int>(judged.size());
  if (!judged.empty()) {
    DenoiseGuides guides;
    {
      std::lock_guard lock(guides_mutex_);
      if (guides_.albedo.empty()) {
        const PrimaryBuffers primary = render_primary_buffers(scene_, camera_, true, reach_.affected);
        guides_ = {primary.albedo, primary.normal, primary.depth, primary.prop_coverage};
      }
      guides = guides_;
    }
    // The odd half has about half the samples: twice the variance of the full mean.
    const ChangeBuffer odd{b.odd, b.variance * 2.0};
    const cv::Mat odd_filtered = denoise_change(odd, b.touched, out.coverage, guides, settings_.denoise_options);
    const std::vector<bool> helps = filter_helps_per_tile(b.odd, odd_filtered, b.even, b.touched, judged);
    const cv::Mat filtered = denoise_change({out.change, b.variance}, b.touched, out.coverage, guides, settings_.denoise_options);
    for (size_t i = 0; i < judged.size(); ++i)
      if (helps[i]) {
        filtered(judged[i]).copyTo(out.change(judged[i]));
        ++r.tiles_filtered;
      }
  }
  r.seconds = seconds_since(start);
  if (report) *report = r;
  return out;
}

cv::Mat RenderSession::composite() const {
  return composite_differential(photo_, settings_.denoise ? denoised() : differential());
}

cv::Mat RenderSession::touched() const {
  cv::Mat mask(camera_.height, camera_.width, CV_8U, cv::Scalar(0));
  for_each_traced_pixel([&](int x, int y, const DifferentialPixel& p) {
    if (touched_by_prop(p)) mask.at<uint8_t>(y, x) = 255;
  });
  return mask;
}

cv::Mat RenderSession::tile_error_map() const {
  cv::Mat map(camera_.height, camera_.width, CV_32F, cv::Scalar(0));
  for (const auto& t : tiles_)
    if (t.affected) map(t.rect).setTo(static_cast<float>(t.relative_error));
  return map;
}

RenderStats RenderSession::stats() const {
  RenderStats s;
  s.seconds = total_seconds_;
  for_each_traced_pixel([&](int, int, const DifferentialPixel& p) {
    s.camera_samples += p.samples;
    s.rays += p.rays;
    s.paths_without_prop += p.second_paths;
    s.paths_prop_untouched += p.untouched;
  });
  return s;
}

}  // namespace propcam::render
