// Camera recordings: the input is recording.json; the folder also holds
// kRawFrames raw files of kRawFrameBytes each (what the seed's 4x2 YUYV
// frames need), so manifests that match them load and are converted.
#include <cstddef>
#include <cstdint>
#include <exception>

#include "fuzz_support.h"
#include "propcam/capture/recording.h"

namespace {
constexpr int kRawFrames = 4;
constexpr std::size_t kRawFrameBytes = 16;
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace propcam;
  const auto dir = fuzz::fresh_scratch_dir();
  fuzz::write_file(dir / capture::kRecordingManifest, fuzz::as_text(data, size));
  const std::string raw(kRawFrameBytes, '\x80');
  for (int i = 0; i < kRawFrames; ++i)
    fuzz::write_file(dir / ("frame_00000" + std::to_string(i) + ".raw"), raw);
  try {
    const capture::Recording recording = capture::load_recording(dir);
    capture::load_recording_frames(recording);
  } catch (const std::exception&) {
    // The manifest was rejected with a message naming what is wrong.
  }
  return 0;
}
