#include "propcam/capture/replay_source.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace propcam::capture {
namespace {

std::int64_t steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::chrono::steady_clock::time_point steady_at(std::int64_t ns) {
  return std::chrono::steady_clock::time_point(
      std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::nanoseconds(ns)));
}

constexpr double kDefaultFps = 30;  // the pace of a recording whose rate cannot be told (one frame)

}  // namespace

ReplaySource::ReplaySource(const std::filesystem::path& dir, ReplayOptions options)
    : recording_(load_recording(dir)), frames_(load_recording_frames(recording_)), options_(options) {
  const auto& recorded = recording_.frames;
  const std::int64_t first = recorded.front().metadata.timestamp_ns;
  for (const RecordedFrame& f : recorded) offsets_ns_.push_back(f.metadata.timestamp_ns - first);
  const std::int64_t span = offsets_ns_.back();
  // Keeps the schedule's arithmetic far from overflow (and catches bogus clocks).
  constexpr std::int64_t kMaxSpanNs = std::int64_t{30} * 24 * 3600 * 1'000'000'000;
  if (span > kMaxSpanNs)
    throw std::runtime_error(recording_.dir.string() + ": the recording spans " + std::to_string(span / 1'000'000'000) +
                             " s, more than 30 days; its timestamps cannot be replayed");
  if (recorded.size() > 1 && span > 0) recorded_fps_ = static_cast<double>(recorded.size() - 1) * 1e9 / span;
  sequences_increase_ = std::adjacent_find(recorded.begin(), recorded.end(), [](const auto& a, const auto& b) {
                          return b.metadata.sequence <= a.metadata.sequence;
                        }) == recorded.end();
  config_.pixel_format = recording_.format.pixel_format;
  config_.width = recording_.format.width;
  config_.height = recording_.format.height;
  config_.fps = recorded_fps_;
}

CameraInfo ReplaySource::info() const {
  CameraInfo info;
  info.id = "replay:" + recording_.dir.string();
  info.backend = "replay";
  info.description = "replay of " + (recording_.camera_description.empty()
                                          ? recording_.camera_id
                                          : recording_.camera_description + " (" + recording_.camera_id + ")");
  FormatSizes sizes;
  sizes.pixel_format = recording_.format.pixel_format;
  sizes.sizes.push_back({recording_.format.width, recording_.format.height});
  info.formats.push_back(sizes);
  return info;
}

ConfigStatus ReplaySource::configure(StreamConfig& config) {
  std::lock_guard lock(mutex_);
  if (running_) throw std::logic_error("replay " + recording_.dir.string() + ": configure while running");
  ConfigStatus status = ConfigStatus::Valid;
  const FrameFormat& f = recording_.format;
  if (config.pixel_format != f.pixel_format || config.width != f.width || config.height != f.height) {
    config.pixel_format = f.pixel_format;
    config.width = f.width;
    config.height = f.height;
    status = ConfigStatus::Adjusted;
  }
  // fps 0 asks for the camera's default, which is the recorded rate.
  const bool fps_differs = recorded_fps_ > 0 && config.fps != 0 &&
                           !(std::abs(config.fps - recorded_fps_) <= 0.01 * recorded_fps_);
  if (fps_differs || (recorded_fps_ == 0 && !(config.fps >= 0 && std::isfinite(config.fps)))) {
    config.fps = recorded_fps_;
    status = ConfigStatus::Adjusted;
  }
  config_ = config;
  return status;
}

StreamConfig ReplaySource::configuration() const {
  std::lock_guard lock(mutex_);
  return config_;
}

void ReplaySource::start() {
  std::lock_guard lock(mutex_);
  if (running_) return;
  running_ = true;
  ended_ = false;
  position_ = 0;
  loop_ = 0;
  sequence_base_ = next_sequence_;
  epoch_ns_ = steady_now_ns();
  const std::int64_t span = offsets_ns_.back();
  const double fps = config_.fps > 0 ? config_.fps : kDefaultFps;
  // The gap from the last frame back to the first: one mean interval (a
  // microsecond to an hour, whatever fps a one-frame recording was given).
  const std::int64_t period = recorded_fps_ > 0 ? span / static_cast<std::int64_t>(frames_.size() - 1)
                                                : static_cast<std::int64_t>(std::clamp(1e9 / fps, 1e3, 3.6e12));
  loop_ns_ = span + std::max<std::int64_t>(period, 1);
}

void ReplaySource::stop() {
  {
    std::lock_guard lock(mutex_);
    running_ = false;
  }
  wake_.notify_all();
}

bool ReplaySource::running() const {
  std::lock_guard lock(mutex_);
  return running_;
}

std::int64_t ReplaySource::scheduled_ns(std::uint64_t loop, std::size_t index) const {
  return epoch_ns_ + static_cast<std::int64_t>(loop) * loop_ns_ + offsets_ns_[index];
}

// A live camera hands a late client its newest frame, not a backlog: move
// to the latest frame already due (the skipped ones show as sequence gaps).
void ReplaySource::skip_overdue_locked(std::int64_t now_ns) {
  if (now_ns < epoch_ns_) return;
  const std::int64_t elapsed = now_ns - epoch_ns_;
  auto loop = static_cast<std::uint64_t>(elapsed / loop_ns_);
  const std::int64_t into_loop = elapsed % loop_ns_;
  std::size_t index =
      static_cast<std::size_t>(std::upper_bound(offsets_ns_.begin(), offsets_ns_.end(), into_loop) - offsets_ns_.begin()) - 1;
  if (!options_.loop && loop > 0) {
    loop = 0;
    index = frames_.size() - 1;
  }
  if (loop > loop_ || (loop == loop_ && index > position_)) {
    loop_ = loop;
    position_ = index;
  }
}

Frame ReplaySource::deliver_locked(std::int64_t timestamp_ns) {
  const std::size_t n = frames_.size();
  Frame frame = frames_[position_];  // shares the loaded bytes
  const auto& recorded = recording_.frames;
  std::uint64_t offset = position_ + loop_ * n;
  if (sequences_increase_) {
    const std::uint64_t first = recorded.front().metadata.sequence;
    const std::uint64_t span = recorded.back().metadata.sequence - first + 1;
    offset = recorded[position_].metadata.sequence - first + loop_ * span;  // keeps recorded drops
  }
  frame.metadata.sequence = sequence_base_ + offset;
  frame.metadata.timestamp_ns = std::max(timestamp_ns, last_timestamp_ns_);
  next_sequence_ = frame.metadata.sequence + 1;
  last_timestamp_ns_ = frame.metadata.timestamp_ns;
  if (++position_ == n) {
    if (options_.loop) {
      position_ = 0;
      ++loop_;
    } else {
      position_ = n - 1;
      ended_ = true;
    }
  }
  return frame;
}

CaptureResult ReplaySource::next_locked(std::unique_lock<std::mutex>& lock, std::chrono::milliseconds timeout,
                                        bool paced) {
  const auto end_of_stream = [&] {
    return CaptureResult{CaptureStatus::EndOfStream, std::nullopt, "end of recording " + recording_.dir.string()};
  };
  if (ended_) return end_of_stream();
  if (!paced) return CaptureResult{CaptureStatus::Ok, deliver_locked(std::max(steady_now_ns(), last_timestamp_ns_ + 1)), ""};

  const std::int64_t deadline = steady_now_ns() + std::max<std::int64_t>(0, std::chrono::nanoseconds(timeout).count());
  while (true) {
    const std::int64_t now = steady_now_ns();
    skip_overdue_locked(now);
    const std::int64_t due = scheduled_ns(loop_, position_);
    if (due <= now) return CaptureResult{CaptureStatus::Ok, deliver_locked(due), ""};
    if (due > deadline) {
      wake_.wait_until(lock, steady_at(deadline), [&] { return !running_; });
      return CaptureResult{CaptureStatus::Timeout, std::nullopt,
                           running_ ? "no recorded frame due within " + std::to_string(timeout.count()) + " ms"
                                    : "replay stopped"};
    }
    if (wake_.wait_until(lock, steady_at(due), [&] { return !running_; }))
      return CaptureResult{CaptureStatus::Timeout, std::nullopt, "replay stopped"};
    if (ended_) return end_of_stream();  // another caller took the last frame meanwhile
  }
}

CaptureResult ReplaySource::next_frame(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  if (!running_) throw std::logic_error("replay " + recording_.dir.string() + ": next_frame before start");
  return next_locked(lock, timeout, options_.pacing == ReplayPacing::Realtime);
}

CaptureResult ReplaySource::capture_still(const std::optional<StreamConfig>&, std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  return next_locked(lock, timeout, running_ && options_.pacing == ReplayPacing::Realtime);
}

std::vector<std::string> ReplaySource::set_controls(const CameraControls& c) {
  std::vector<std::string> ignored;
  if (c.exposure_us) ignored.push_back("exposure_us");
  if (c.analogue_gain) ignored.push_back("analogue_gain");
  if (c.colour_gain_red) ignored.push_back("colour_gain_red");
  if (c.colour_gain_blue) ignored.push_back("colour_gain_blue");
  if (c.auto_exposure) ignored.push_back("auto_exposure");
  if (c.auto_white_balance) ignored.push_back("auto_white_balance");
  return ignored;
}

}  // namespace propcam::capture
