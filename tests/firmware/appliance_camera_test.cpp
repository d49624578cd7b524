// The appliance's camera thread against the real replay camera and the real
// capture daemon: frames flow, a still arrives with its request id, and a
// camera that goes away (the daemon stops) is reported on the viewfinder and
// picked up again when it comes back, without the UI doing anything.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <thread>

#include "appliance/appliance_camera.h"
#include "propcam/capture/camera_registry.h"
#include "propcam/capture/capture_server.h"

namespace propcam::firmware {
namespace {
namespace fs = std::filesystem;
using namespace std::chrono_literals;

const std::string kRecording = "replay:" + (fs::path(PROPCAM_SOURCE_DIR) / "board/virtual/recordings/living_room").string();

capture::StreamConfig viewfinder() {
  capture::StreamConfig c;
  c.pixel_format = capture::PixelFormat::YUYV;
  c.width = 640;
  c.height = 480;
  c.fps = 30;
  return c;
}

// Waits up to `limit` for `done`, polling.
template <typename Predicate>
bool eventually(Predicate done, std::chrono::milliseconds limit = 10s) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < end) {
    if (done()) return true;
    std::this_thread::sleep_for(10ms);
  }
  return done();
}

struct StillInbox {
  std::mutex mutex;
  std::vector<StillResult> stills;
  void put(StillResult r) {
    std::lock_guard lock(mutex);
    stills.push_back(std::move(r));
  }
  size_t size() {
    std::lock_guard lock(mutex);
    return stills.size();
  }
};

TEST(ApplianceCamera, StreamsAndTakesAStillFromTheReplayCamera) {
  StillInbox inbox;
  ApplianceCameraOptions o;
  o.camera_id = kRecording;
  o.viewfinder = viewfinder();
  ApplianceCamera camera(o, [&](StillResult r) { inbox.put(std::move(r)); });
  ASSERT_TRUE(eventually([&] { return camera.latest().number >= 3; })) << camera.latest().problem;
  const ViewfinderFrame frame = camera.latest();
  EXPECT_EQ(frame.rgb8.cols, 640);
  EXPECT_EQ(frame.rgb8.rows, 480);
  EXPECT_TRUE(frame.problem.empty());
  camera.request_still(7);
  ASSERT_TRUE(eventually([&] { return inbox.size() == 1; }));
  std::lock_guard lock(inbox.mutex);
  EXPECT_EQ(inbox.stills[0].request, 7u);
  EXPECT_TRUE(inbox.stills[0].error.empty()) << inbox.stills[0].error;
  EXPECT_EQ(inbox.stills[0].linear.type(), CV_32FC3);
  EXPECT_EQ(inbox.stills[0].rgb8.size(), cv::Size(640, 480));
}

TEST(ApplianceCamera, AMissingCameraIsReportedAndAStillFailsClearly) {
  StillInbox inbox;
  ApplianceCameraOptions o;
  o.camera_id = "replay:/nonexistent/recording";
  o.viewfinder = viewfinder();
  o.reopen_delay = 50ms;
  ApplianceCamera camera(o, [&](StillResult r) { inbox.put(std::move(r)); });
  ASSERT_TRUE(eventually([&] { return camera.latest().problem.find("unavailable") != std::string::npos; }))
      << camera.latest().problem;
  camera.request_still(3);
  ASSERT_TRUE(eventually([&] { return inbox.size() == 1; }));
  std::lock_guard lock(inbox.mutex);
  EXPECT_EQ(inbox.stills[0].request, 3u);
  EXPECT_FALSE(inbox.stills[0].error.empty());
  EXPECT_TRUE(inbox.stills[0].linear.empty());
}

TEST(ApplianceCamera, ACameraThatGoesAwayIsPickedUpAgainWhenItReturns) {
  const fs::path socket = fs::temp_directory_path() / ("propcam_appcam_" + std::to_string(::getpid()) + ".sock");
  fs::remove(socket);
  capture::CaptureServerOptions so;
  so.socket_path = socket.string();
  so.camera_id = kRecording;
  so.stream = viewfinder();
  auto factory = [](const std::string& id) { return capture::open_camera(id); };
  auto server = std::make_unique<capture::CaptureServer>(factory, so);
  server->start();

  ApplianceCameraOptions o;
  o.daemon_socket = socket.string();
  o.viewfinder = viewfinder();
  o.reopen_delay = 50ms;
  o.reopen_delay_max = 200ms;
  ApplianceCamera camera(o, [](StillResult) {});
  ASSERT_TRUE(eventually([&] { return camera.latest().number >= 2; })) << camera.latest().problem;

  server.reset();  // the daemon (and its camera) is gone
  ASSERT_TRUE(eventually([&] { return !camera.latest().problem.empty(); })) << "the viewfinder says the camera is gone";
  const std::uint64_t before = camera.latest().number;

  server = std::make_unique<capture::CaptureServer>(factory, so);
  server->start();
  ASSERT_TRUE(eventually([&] { return camera.latest().number > before + 2 && camera.latest().problem.empty(); }))
      << camera.latest().problem;
  server.reset();
  fs::remove(socket);
}

}  // namespace
}  // namespace propcam::firmware
