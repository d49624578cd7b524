// A recording of a camera stream: a folder holding recording.json (the
// camera, the frame format and one entry per frame with its metadata) and
// one raw file per frame with the frame's bytes exactly as the camera
// delivered them (frame_000000.raw, ...). Replaying it (replay_source.h)
// runs the same conversion code as the live camera did.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "propcam/capture/frame.h"

namespace propcam::capture {

inline constexpr int kRecordingVersion = 1;
inline constexpr const char* kRecordingManifest = "recording.json";
// Replay holds every frame in memory; larger recordings are refused.
inline constexpr std::size_t kMaxRecordingBytes = std::size_t{512} << 20;

struct RecordedFrame {
  std::string file;            // a plain file name inside the recording folder
  std::size_t bytes_used = 0;  // the raw file's size
  FrameMetadata metadata;
};

struct Recording {
  std::filesystem::path dir;
  int version = kRecordingVersion;
  std::string camera_id;           // the camera it came from ("v4l2:/dev/video0", ...)
  std::string camera_description;
  FrameFormat format;              // every frame's format
  std::vector<RecordedFrame> frames;

  std::size_t total_bytes() const;
};

// Writes a recording. Each raw file and, at finish(), recording.json are
// written atomically (temporary name, fsync, rename), so a crash leaves no
// half-written file under a final name. A folder whose recording was never
// finished has no recording.json and does not load.
class Recorder {
 public:
  // Creates `dir` (and its parents) if needed; throws std::runtime_error if
  // it exists and is not an empty folder.
  Recorder(std::filesystem::path dir, std::string camera_id, std::string camera_description = {});
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  // Stores the frame's bytes and metadata. The first frame fixes the
  // recording's format; later frames must have the same one. Throws on an
  // invalid format, a mismatch, a frame of no bytes, after finish(), or when
  // the recording would exceed kMaxRecordingBytes.
  void append(const Frame& frame);
  // Writes recording.json; throws if no frame was appended. Returns what was written.
  const Recording& finish();

  std::size_t frame_count() const { return recording_.frames.size(); }
  bool finished() const { return finished_; }

 private:
  Recording recording_;
  bool finished_ = false;
};

// Reads and checks recording.json and the raw files' sizes (not their
// bytes). Throws std::runtime_error naming the file and what is wrong:
// missing or garbled JSON, a missing or mistyped field, an unknown pixel
// format, bad dimensions, a frame file name that is not a plain name inside
// the folder, a missing raw file or one whose size differs from bytes_used,
// timestamps going backwards, no frames, or more than kMaxRecordingBytes.
Recording load_recording(const std::filesystem::path& dir);

// The recorded frames with their bytes, read in full (sizes checked again).
std::vector<Frame> load_recording_frames(const Recording& recording);

}  // namespace propcam::capture
