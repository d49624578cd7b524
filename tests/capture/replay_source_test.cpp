#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <thread>

#include "propcam/capture/pixel_format.h"
#include "propcam/capture/replay_source.h"

namespace propcam::capture {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;

constexpr std::int64_t kMs = 1'000'000;

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("propcam_replay_test_" + std::to_string(::getpid())) / name;
  fs::remove_all(dir);
  fs::create_directories(dir.parent_path());
  return dir;
}

// Frame i is a flat grey of level 10 * (i + 1), so bytes tell frames apart.
Frame grey_frame(int i) {
  FrameFormat f;
  f.pixel_format = PixelFormat::YUYV;
  f.width = 8;
  f.height = 6;
  const cv::Mat img(6, 8, CV_8UC3, cv::Scalar::all(10 * (i + 1)));
  return rgb8_to_frame(img, f);
}

// A recording with the given timestamps (ns, any origin) and sequences.
fs::path make_recording(const std::string& name, const std::vector<std::int64_t>& timestamps,
                        const std::vector<std::uint64_t>& sequences) {
  const fs::path dir = fresh_dir(name);
  Recorder recorder(dir, "v4l2:/dev/video3", "Test Cam");
  for (std::size_t i = 0; i < timestamps.size(); ++i) {
    Frame f = grey_frame(static_cast<int>(i));
    f.metadata.timestamp_ns = timestamps[i];
    f.metadata.sequence = sequences[i];
    f.metadata.exposure_us = 100.0 * (i + 1);
    recorder.append(f);
  }
  recorder.finish();
  return dir;
}

// Which recorded frame this is, from its bytes.
int frame_index(const Frame& f) { return f.data()[0]; }

int index_of_recorded(int i) { return grey_frame(i).data()[0]; }

std::int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

ReplayOptions as_fast(bool loop = true) {
  ReplayOptions o;
  o.loop = loop;
  o.pacing = ReplayPacing::AsFastAsPossible;
  return o;
}

// ---------------------------------------------------------------------------

TEST(ReplaySource, DescribesItselfAsTheRecordedCamera) {
  const fs::path dir = make_recording("info", {0, 33 * kMs}, {0, 1});
  ReplaySource source(dir);
  const CameraInfo info = source.info();
  EXPECT_EQ(info.id, "replay:" + dir.string());
  EXPECT_EQ(info.backend, "replay");
  EXPECT_NE(info.description.find("Test Cam"), std::string::npos) << info.description;
  EXPECT_NE(info.description.find("v4l2:/dev/video3"), std::string::npos) << info.description;
  ASSERT_EQ(info.formats.size(), 1u);
  EXPECT_EQ(info.formats[0].pixel_format, PixelFormat::YUYV);
  ASSERT_EQ(info.formats[0].sizes.size(), 1u);
  EXPECT_EQ(info.formats[0].sizes[0].width, 8);
  EXPECT_EQ(info.formats[0].sizes[0].height, 6);
  EXPECT_NEAR(source.recorded_fps(), 1000.0 / 33, 1e-9);
  const StreamConfig c = source.configuration();
  EXPECT_EQ(c.pixel_format, PixelFormat::YUYV);
  EXPECT_EQ(c.width, 8);
  EXPECT_EQ(c.height, 6);
  EXPECT_FALSE(source.running());
}

TEST(ReplaySource, ConfigureAdjustsToTheRecording) {
  ReplaySource source(make_recording("configure", {0, 40 * kMs, 80 * kMs}, {0, 1, 2}));  // 25 fps
  StreamConfig same{PixelFormat::YUYV, 8, 6, 25};
  EXPECT_EQ(source.configure(same), ConfigStatus::Valid);
  StreamConfig default_fps{PixelFormat::YUYV, 8, 6, 0};
  EXPECT_EQ(source.configure(default_fps), ConfigStatus::Valid);
  StreamConfig other{PixelFormat::MJPEG, 1920, 1080, 25};
  EXPECT_EQ(source.configure(other), ConfigStatus::Adjusted);
  EXPECT_EQ(other.pixel_format, PixelFormat::YUYV);
  EXPECT_EQ(other.width, 8);
  EXPECT_EQ(other.height, 6);
  StreamConfig faster{PixelFormat::YUYV, 8, 6, 60};
  EXPECT_EQ(source.configure(faster), ConfigStatus::Adjusted);
  EXPECT_DOUBLE_EQ(faster.fps, 25);
  EXPECT_DOUBLE_EQ(source.configuration().fps, 25);
  source.start();
  EXPECT_THROW(source.configure(same), std::logic_error);
}

TEST(ReplaySource, AsFastDeliversEveryFrameInOrderAndLoops) {
  // Recorded sequence 100, 101, 103: the camera dropped one; replay keeps the gap.
  ReplaySource source(make_recording("as_fast", {5 * kMs, 38 * kMs, 105 * kMs}, {100, 101, 103}), as_fast());
  EXPECT_THROW(source.next_frame(milliseconds(10)), std::logic_error);  // not started
  source.start();
  EXPECT_TRUE(source.running());
  const std::vector<std::uint64_t> sequences = {0, 1, 3, 4, 5, 7, 8};
  std::int64_t last_timestamp = 0;
  for (std::size_t i = 0; i < sequences.size(); ++i) {
    const CaptureResult r = source.next_frame(milliseconds(0));
    ASSERT_EQ(r.status, CaptureStatus::Ok) << r.message;
    ASSERT_TRUE(r.frame);
    EXPECT_EQ(frame_index(*r.frame), index_of_recorded(static_cast<int>(i % 3))) << i;
    EXPECT_EQ(r.frame->metadata.sequence, sequences[i]);
    EXPECT_EQ(r.frame->metadata.exposure_us, 100.0 * (i % 3 + 1));
    EXPECT_GT(r.frame->metadata.timestamp_ns, last_timestamp);
    EXPECT_LE(r.frame->metadata.timestamp_ns, steady_ns());  // re-based to now, not the recorded clock
    last_timestamp = r.frame->metadata.timestamp_ns;
    EXPECT_EQ(frame_to_rgb8(*r.frame).at<cv::Vec3b>(0, 0), cv::Vec3b::all(10 * (i % 3 + 1)));
  }
}

TEST(ReplaySource, WithoutLoopTheStreamEnds) {
  ReplaySource source(make_recording("no_loop", {0, 1 * kMs, 2 * kMs}, {0, 1, 2}), as_fast(false));
  source.start();
  for (int i = 0; i < 3; ++i) EXPECT_EQ(source.next_frame(milliseconds(0)).status, CaptureStatus::Ok);
  for (int i = 0; i < 2; ++i) {
    const CaptureResult r = source.next_frame(milliseconds(0));
    EXPECT_EQ(r.status, CaptureStatus::EndOfStream);
    EXPECT_FALSE(r.frame);
    EXPECT_NE(r.message.find("end of recording"), std::string::npos) << r.message;
  }
  EXPECT_EQ(source.capture_still(std::nullopt, milliseconds(0)).status, CaptureStatus::EndOfStream);
  // A restart plays it again, numbering on from where it stopped.
  source.stop();
  source.start();
  const CaptureResult again = source.next_frame(milliseconds(0));
  ASSERT_EQ(again.status, CaptureStatus::Ok);
  EXPECT_EQ(frame_index(*again.frame), index_of_recorded(0));
  EXPECT_EQ(again.frame->metadata.sequence, 3u);
}

TEST(ReplaySource, SequencesWithoutOrderAreNumberedByIndex) {
  ReplaySource source(make_recording("flat_sequence", {0, 1 * kMs, 2 * kMs}, {0, 0, 0}), as_fast());
  source.start();
  for (std::uint64_t i = 0; i < 5; ++i) EXPECT_EQ(source.next_frame(milliseconds(0)).frame->metadata.sequence, i);
}

TEST(ReplaySource, RealtimeKeepsTheRecordedSpacing) {
  // 2 ms apart: the test reads whatever is due and checks order and spacing,
  // which come from the schedule, not from how fast this machine is.
  ReplaySource source(make_recording("realtime", {7 * kMs, 9 * kMs, 11 * kMs}, {50, 51, 52}));
  source.start();
  std::optional<Frame> first;
  std::uint64_t last_sequence = 0;
  std::int64_t last_timestamp = 0;
  for (int i = 0; i < 12; ++i) {
    const CaptureResult r = source.next_frame(milliseconds(2000));
    ASSERT_EQ(r.status, CaptureStatus::Ok) << r.message;
    const Frame& f = *r.frame;
    EXPECT_LE(f.metadata.timestamp_ns, steady_ns());  // never handed out before it is due
    if (!first) {
      first = f;  // frame 0 unless this machine was slow to ask
    } else {
      EXPECT_GT(f.metadata.sequence, last_sequence);  // a slow reader may skip frames, never repeat
      EXPECT_GE(f.metadata.timestamp_ns, last_timestamp);
    }
    // Frame k of the stream (loops of 3 frames, 6 ms each) is due 2 ms * k after the first.
    EXPECT_EQ(f.metadata.timestamp_ns - first->metadata.timestamp_ns,
              static_cast<std::int64_t>(f.metadata.sequence - first->metadata.sequence) * 2 * kMs);
    EXPECT_EQ(frame_index(f), index_of_recorded(static_cast<int>(f.metadata.sequence % 3)));
    last_sequence = f.metadata.sequence;
    last_timestamp = f.metadata.timestamp_ns;
  }
}

TEST(ReplaySource, RealtimeHandsALateReaderTheNewestFrame) {
  // As a live camera: after a pause the reader gets the frame due now, not a
  // backlog. A sleep lasts at least as long as asked, so at least 10 frames
  // of 2 ms are due by then (a lower bound only: no wall-clock assertion).
  ReplaySource source(make_recording("late", {0, 2 * kMs, 4 * kMs}, {0, 1, 2}));
  source.start();
  std::this_thread::sleep_for(milliseconds(20));
  const CaptureResult late = source.next_frame(milliseconds(1000));
  ASSERT_EQ(late.status, CaptureStatus::Ok);
  EXPECT_GE(late.frame->metadata.sequence, 10u);
  const CaptureResult next = source.next_frame(milliseconds(1000));
  ASSERT_EQ(next.status, CaptureStatus::Ok);
  EXPECT_GT(next.frame->metadata.sequence, late.frame->metadata.sequence);
}

TEST(ReplaySource, RealtimeTimesOutBeforeTheNextFrameIsDue) {
  // The second frame is an hour after the first.
  ReplaySource source(make_recording("hour", {0, 3'600'000 * kMs}, {0, 1}));
  source.start();
  EXPECT_EQ(source.next_frame(milliseconds(0)).status, CaptureStatus::Ok);
  const CaptureResult r = source.next_frame(milliseconds(5));
  EXPECT_EQ(r.status, CaptureStatus::Timeout);
  EXPECT_FALSE(r.frame);
  EXPECT_NE(r.message.find("no recorded frame due"), std::string::npos) << r.message;
  EXPECT_TRUE(source.running());  // a timeout leaves the source usable
}

TEST(ReplaySource, StopEndsAWait) {
  ReplaySource source(make_recording("stop", {0, 3'600'000 * kMs}, {0, 1}));
  source.start();
  ASSERT_EQ(source.next_frame(milliseconds(0)).status, CaptureStatus::Ok);
  std::thread stopper([&] {
    std::this_thread::sleep_for(milliseconds(50));
    source.stop();
  });
  // Whether stop() lands before or during the wait, no frame comes out.
  try {
    const CaptureResult r = source.next_frame(milliseconds(60'000));
    EXPECT_EQ(r.status, CaptureStatus::Timeout);
    EXPECT_EQ(r.message, "replay stopped");
  } catch (const std::logic_error&) {
    SUCCEED();  // stopped before next_frame began
  }
  stopper.join();
  EXPECT_FALSE(source.running());
  EXPECT_THROW(source.next_frame(milliseconds(0)), std::logic_error);
}

TEST(ReplaySource, StillsAndControls) {
  ReplaySource source(make_recording("still", {0, 3'600'000 * kMs}, {0, 1}));
  // Stopped: a still is the next frame at once, at the recorded size whatever is asked.
  const StreamConfig big{PixelFormat::MJPEG, 4000, 3000, 0};
  const CaptureResult a = source.capture_still(big, milliseconds(0));
  ASSERT_EQ(a.status, CaptureStatus::Ok);
  EXPECT_EQ(a.frame->format.width, 8);
  EXPECT_EQ(a.frame->format.pixel_format, PixelFormat::YUYV);
  EXPECT_EQ(frame_index(*a.frame), index_of_recorded(0));
  const CaptureResult b = source.capture_still(std::nullopt, milliseconds(0));
  ASSERT_EQ(b.status, CaptureStatus::Ok);
  EXPECT_EQ(frame_index(*b.frame), index_of_recorded(1));
  EXPECT_GT(b.frame->metadata.sequence, a.frame->metadata.sequence);
  EXPECT_FALSE(source.running());

  CameraControls controls;
  controls.exposure_us = 5000;
  controls.auto_white_balance = false;
  EXPECT_EQ(source.set_controls(controls), (std::vector<std::string>{"exposure_us", "auto_white_balance"}));
  EXPECT_TRUE(source.set_controls(CameraControls{}).empty());
}

TEST(ReplaySource, SingleFrameRecordingsLoop) {
  ReplaySource source(make_recording("single", {123}, {9}), as_fast());
  EXPECT_EQ(source.recorded_fps(), 0);
  StreamConfig c{PixelFormat::YUYV, 8, 6, 15};
  EXPECT_EQ(source.configure(c), ConfigStatus::Valid);  // nothing recorded to contradict it
  source.start();
  for (std::uint64_t i = 0; i < 3; ++i) {
    const CaptureResult r = source.next_frame(milliseconds(0));
    ASSERT_EQ(r.status, CaptureStatus::Ok);
    EXPECT_EQ(r.frame->metadata.sequence, i);
  }
}

TEST(ReplaySource, BrokenRecordingsNameTheFile) {
  const fs::path missing = fresh_dir("missing");
  try {
    ReplaySource source(missing);
    FAIL() << "opened a folder without a recording";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find((missing / "recording.json").string()), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace propcam::capture
