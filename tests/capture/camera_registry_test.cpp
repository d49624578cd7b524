// Cameras by id across the backends: the replay backend is the one every
// machine has, so the registry is tested through recordings made here.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "propcam/capture/camera_registry.h"
#include "propcam/capture/pixel_format.h"
#include "propcam/capture/recording.h"

namespace propcam::capture {
namespace {

namespace fs = std::filesystem;

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::path(::testing::TempDir()) / "propcam_registry" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

void record_two_frames(const fs::path& dir) {
  FrameFormat format;
  format.pixel_format = PixelFormat::YUYV;
  format.width = 32;
  format.height = 16;
  format.stride = minimum_stride(format.pixel_format, format.width);
  Recorder recorder(dir, "v4l2:/dev/video9", "Registry Cam");
  for (int i = 0; i < 2; ++i) {
    Frame f = rgb8_to_frame(cv::Mat(16, 32, CV_8UC3, cv::Scalar(40 * i, 90, 200)), format);
    f.metadata.sequence = static_cast<std::uint64_t>(i);
    f.metadata.timestamp_ns = i * 33'333'333;
    recorder.append(f);
  }
  recorder.finish();
}

std::vector<CameraInfo> replays(const std::vector<CameraInfo>& all) {
  std::vector<CameraInfo> out;
  for (const auto& c : all)
    if (c.backend == "replay") out.push_back(c);
  return out;
}

TEST(CameraRegistry, ListsRecordingsInAFolderSortedAndTheFolderItself) {
  const fs::path root = fresh_dir("list");
  record_two_frames(root / "b_second");
  record_two_frames(root / "a_first");
  fs::create_directories(root / "not_a_recording");
  const auto found = replays(list_cameras({root.string()}));
  ASSERT_EQ(found.size(), 2u);
  EXPECT_EQ(found[0].id, "replay:" + (root / "a_first").string());
  EXPECT_EQ(found[1].id, "replay:" + (root / "b_second").string());
  ASSERT_EQ(found[0].formats.size(), 1u);
  EXPECT_EQ(found[0].formats[0].pixel_format, PixelFormat::YUYV);
  // A folder that is itself a recording.
  EXPECT_EQ(replays(list_cameras({(root / "a_first").string()})).size(), 1u);
}

TEST(CameraRegistry, ABrokenRecordingIsListedAsUnusableNotFatal) {
  const fs::path root = fresh_dir("broken");
  record_two_frames(root / "good");
  fs::create_directories(root / "bad");
  std::ofstream(root / "bad" / kRecordingManifest) << "{ not json";
  const auto found = replays(list_cameras({root.string()}));
  ASSERT_EQ(found.size(), 2u);
  EXPECT_TRUE(found[0].formats.empty());
  EXPECT_NE(found[0].description.find("unusable"), std::string::npos) << found[0].description;
  EXPECT_FALSE(found[1].formats.empty());
}

TEST(CameraRegistry, OpensAReplayByIdAndStreamsIt) {
  const fs::path dir = fresh_dir("open") / "rec";
  record_two_frames(dir);
  const auto source = open_camera("replay:" + dir.string());
  ASSERT_TRUE(source);
  EXPECT_EQ(source->info().backend, "replay");
  source->start();
  const CaptureResult r = source->next_frame(std::chrono::milliseconds(2000));
  ASSERT_EQ(r.status, CaptureStatus::Ok) << r.message;
  const cv::Mat rgb = frame_to_rgb8(*r.frame);
  EXPECT_EQ(rgb.size(), cv::Size(32, 16));
  source->stop();
}

TEST(CameraRegistry, UnknownBackendsAndMissingCamerasAreClearErrors) {
  const auto message = [](const std::string& id) {
    try {
      open_camera(id);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("webcam0").find("unknown backend"), std::string::npos);
  EXPECT_NE(message("replay:/nonexistent/rec").find("replay:/nonexistent/rec"), std::string::npos);
  EXPECT_NE(message("v4l2:/nonexistent/video0").find("v4l2:/nonexistent/video0"), std::string::npos);
  EXPECT_NE(message("libcamera:no-such-camera").find("libcamera:no-such-camera"), std::string::npos);
  if (list_cameras().empty()) {
    EXPECT_NE(message("libcamera:auto").find("no camera"), std::string::npos) << message("libcamera:auto");
  }
}

}  // namespace
}  // namespace propcam::capture
