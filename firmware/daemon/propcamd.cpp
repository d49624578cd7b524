// propcamd: owns the camera and serves its frames to the appliance's
// processes over a UNIX socket (capture/include/propcam/capture/capture_server.h).
// Runs until SIGINT / SIGTERM; the camera is reopened by itself when it
// comes back after being unplugged.
//
// Under systemd (board/systemd/propcamd.service, Type=notify) it tells the
// service manager READY=1 once the socket listens, STATUS= on camera changes,
// WATCHDOG=1 from the camera thread and STOPPING=1 on shutdown. Without
// NOTIFY_SOCKET those calls do nothing.
#include <signal.h>
#include <systemd/sd-daemon.h>

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "common/logging.h"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "propcam/capture/camera_registry.h"
#include "propcam/capture/capture_server.h"

namespace {

using namespace propcam::capture;

std::optional<PixelFormat> parse_format(const std::string& name) {
  static const std::map<std::string, PixelFormat> names = {
      {"RGB24", PixelFormat::RGB24}, {"BGR24", PixelFormat::BGR24}, {"YUYV", PixelFormat::YUYV},
      {"UYVY", PixelFormat::UYVY},   {"NV12", PixelFormat::NV12},   {"MJPEG", PixelFormat::MJPEG},
      {"GREY", PixelFormat::GREY}};
  const auto it = names.find(name);
  if (it == names.end()) return std::nullopt;
  return it->second;
}

// The first camera the registry finds, when none was named.
std::string default_camera(const std::vector<std::string>& recordings) {
  const auto cameras = list_cameras(recordings);
  if (cameras.empty()) throw std::runtime_error("no camera found (name one with --camera)");
  return cameras.front().id;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"propcamd: the PropCam capture daemon"};
  app.set_version_flag("--version", std::string("propcamd ") + PROPCAM_VERSION);
  bool quiet = false, verbose = false;
  app.add_flag("-q,--quiet", quiet, "Warnings and errors only");
  app.add_flag("-v,--verbose", verbose, "Debug messages too");
  CaptureServerOptions options;
  std::string format = "YUYV";
  std::vector<std::string> recordings;
  app.add_option("--socket", options.socket_path, "UNIX socket to serve on")->capture_default_str();
  app.add_option("--camera", options.camera_id, "Camera id (v4l2:/dev/video0, libcamera:<id>, replay:<folder>)");
  app.add_option("--width", options.stream.width, "Viewfinder width")->capture_default_str();
  app.add_option("--height", options.stream.height, "Viewfinder height")->capture_default_str();
  app.add_option("--format", format, "Viewfinder pixel format (YUYV, NV12, MJPEG, RGB24, ...)")->capture_default_str();
  app.add_option("--fps", options.stream.fps, "Viewfinder frame rate (0: the camera's default)")->capture_default_str();
  app.add_option("--recordings", recordings, "Folders of replay recordings to list as cameras");
  CLI11_PARSE(app, argc, argv);
  propcam::firmware::set_up_logging(
      "propcamd", quiet ? propcam::firmware::Verbosity::Quiet
                        : verbose ? propcam::firmware::Verbosity::Verbose : propcam::firmware::Verbosity::Normal);

  const auto pixel_format = parse_format(format);
  if (!pixel_format) {
    spdlog::error("unknown pixel format {}", format);
    return 2;
  }
  options.stream.pixel_format = *pixel_format;
  options.log = [](const std::string& line) { spdlog::info("{}", line); };
  options.list_cameras = [recordings] { return list_cameras(recordings); };
  options.status = [](const std::string& line) { sd_notifyf(0, "STATUS=%s", line.c_str()); };
  // The watchdog is fed from the camera thread, at half the period systemd asked
  // for, so a hung camera thread (not just a hung main thread) gets restarted.
  // Its loop turns at least every quarter period, so pings are at most 3/4 apart.
  std::uint64_t watchdog_usec = 0;
  if (sd_watchdog_enabled(0, &watchdog_usec) > 0 && watchdog_usec > 0) {
    const auto half = std::chrono::microseconds(watchdog_usec / 2);
    options.heartbeat_interval = std::max(std::chrono::duration_cast<std::chrono::milliseconds>(half / 2),
                                          std::chrono::milliseconds(1));
    auto last = std::make_shared<std::chrono::steady_clock::time_point>();
    options.heartbeat = [half, last] {
      const auto now = std::chrono::steady_clock::now();
      if (now - *last < half) return;  // the camera thread alone calls this: no lock
      *last = now;
      sd_notify(0, "WATCHDOG=1");
    };
  }

  // Signals go to sigwait below, not to the server's threads.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  if (pthread_sigmask(SIG_BLOCK, &signals, nullptr) != 0) {
    spdlog::error("cannot block signals");
    return 1;
  }
  try {
    if (options.camera_id.empty()) options.camera_id = default_camera(recordings);
    CaptureServer server([](const std::string& id) { return open_camera(id); }, options);
    server.start();
    spdlog::info("propcamd serving {} on {}", options.camera_id, options.socket_path);
    sd_notifyf(0, "READY=1\nSTATUS=serving %s on %s", options.camera_id.c_str(), options.socket_path.c_str());
    int signal_number = 0;
    while (sigwait(&signals, &signal_number) != 0) {
    }
    spdlog::info("propcamd stopping ({})", strsignal(signal_number));
    sd_notify(0, "STOPPING=1");
    server.stop();
  } catch (const std::exception& e) {
    spdlog::error("propcamd: {}", e.what());
    sd_notifyf(0, "STATUS=failed: %s", e.what());
    return 1;
  }
  return 0;
}
