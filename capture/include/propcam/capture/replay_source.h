// A recording (recording.h) played back as a camera: "replay:<folder>".
// Frames come out with the recorded bytes and metadata, but with sequence
// numbers that keep increasing across loops and timestamps re-based to
// steady_clock (CLOCK_MONOTONIC) now, so a client sees a live-like stream.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <vector>

#include "propcam/capture/frame_source.h"
#include "propcam/capture/recording.h"

namespace propcam::capture {

enum class ReplayPacing {
  Realtime,          // each frame released at its recorded interval; a late client skips frames, as live
  AsFastAsPossible,  // every frame in order, at once
};

struct ReplayOptions {
  bool loop = true;  // false: EndOfStream after the last frame
  ReplayPacing pacing = ReplayPacing::Realtime;
};

class ReplaySource final : public FrameSource {
 public:
  // Loads and checks the recording and reads every frame into memory (a
  // recording is at most kMaxRecordingBytes). Throws std::runtime_error
  // naming the file at fault.
  explicit ReplaySource(const std::filesystem::path& dir, ReplayOptions options = {});

  CameraInfo info() const override;
  // Only the recorded pixel format and size are Valid; anything else is
  // Adjusted to them (and fps to the recorded rate when it is known and
  // differs by more than 1%). Throws std::logic_error while running.
  ConfigStatus configure(StreamConfig& config) override;
  StreamConfig configuration() const override;
  // Starts from the first recorded frame, with timestamps from now.
  void start() override;
  void stop() override;
  bool running() const override;

  // Throws std::logic_error when not running.
  CaptureResult next_frame(std::chrono::milliseconds timeout) override;
  // The next frame at the recording's resolution, whatever `still` asks:
  // paced as next_frame when running, at once when stopped.
  CaptureResult capture_still(const std::optional<StreamConfig>& still, std::chrono::milliseconds timeout) override;
  // Replay cannot change what was recorded: returns every control set.
  std::vector<std::string> set_controls(const CameraControls& controls) override;

  const Recording& recording() const { return recording_; }
  // The recorded frame rate from the timestamps (0 when it cannot be told).
  double recorded_fps() const { return recorded_fps_; }

 private:
  std::int64_t scheduled_ns(std::uint64_t loop, std::size_t index) const;
  void skip_overdue_locked(std::int64_t now_ns);
  Frame deliver_locked(std::int64_t timestamp_ns);
  CaptureResult next_locked(std::unique_lock<std::mutex>& lock, std::chrono::milliseconds timeout, bool paced);

  Recording recording_;
  std::vector<Frame> frames_;
  std::vector<std::int64_t> offsets_ns_;  // each frame's time after the first
  ReplayOptions options_;
  double recorded_fps_ = 0;
  bool sequences_increase_ = false;  // else frames are numbered by index

  mutable std::mutex mutex_;
  std::condition_variable wake_;  // stop() interrupts a wait
  StreamConfig config_;
  bool running_ = false;
  bool ended_ = false;
  std::size_t position_ = 0;      // the next frame to deliver
  std::uint64_t loop_ = 0;        // loops completed since start()
  std::int64_t epoch_ns_ = 0;     // when frame 0 of loop 0 is due
  std::int64_t loop_ns_ = 0;      // one pass of the recording, plus one frame interval
  std::uint64_t sequence_base_ = 0;
  std::uint64_t next_sequence_ = 0;  // one past the last delivered
  std::int64_t last_timestamp_ns_ = 0;
};

}  // namespace propcam::capture
