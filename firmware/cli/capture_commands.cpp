#include "cli/capture_commands.h"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <stdexcept>

#include "common/bench_common.h"
#include "propcam/capture/camera_registry.h"
#include "propcam/capture/capture_bench.h"
#include "propcam/capture/capture_client.h"
#include "propcam/capture/image_file.h"
#include "propcam/capture/pixel_format.h"
#include "propcam/capture/recording.h"
#include "propcam/capture/replay_source.h"
#include "propcam/inference/data_dir.h"
#include "propcam/render/vignetting.h"

namespace propcam::firmware {
namespace {

using json = nlohmann::json;
using capture::CaptureStatus;
constexpr std::chrono::milliseconds kFrameTimeout{2000};
// A still may need the stream restarted at a larger size.
constexpr std::chrono::milliseconds kStillTimeout{10000};
constexpr int kMinSide = 16;

json camera_json(const capture::CameraInfo& c) {
  json formats = json::array();
  for (const auto& f : c.formats) {
    json sizes = json::array();
    for (const auto& s : f.sizes) sizes.push_back(std::to_string(s.width) + "x" + std::to_string(s.height));
    formats.push_back({{"format", capture::to_string(f.pixel_format)}, {"sizes", sizes}});
  }
  return {{"id", c.id}, {"backend", c.backend}, {"description", c.description}, {"formats", formats}};
}

std::vector<std::string> recordings_or_bundled(const std::vector<std::string>& dirs) {
  return dirs.empty() ? std::vector<std::string>{bundled_recordings_dir()} : dirs;
}

void add_camera_choice(CLI::App& cmd, CameraChoice& c) {
  cmd.add_option("--camera", c.camera, "Camera id from `propcam cameras` (default: the first attached one)");
  cmd.add_option("--format", c.format, "Pixel format: YUYV, UYVY, NV12, MJPEG, RGB24, BGR24, GREY");
  cmd.add_option("--size", c.size, "Viewfinder size WxH");
  cmd.add_option("--fps", c.fps, "Frame rate")->check(CLI::NonNegativeNumber);
  cmd.add_option("--recordings", c.recordings, "Folders of recordings the default camera may be taken from");
}

// The named camera, else the first attached one (libcamera, V4L2); a
// recording only when --recordings names where to look. With no camera
// attached a shot is an error, never the bundled recording taken silently.
std::string default_camera(const CameraChoice& c) {
  if (!c.camera.empty()) return c.camera;
  for (const auto& info : capture::list_cameras(c.recordings))
    if (!info.formats.empty()) return info.id;
  if (!c.recordings.empty())
    throw std::runtime_error("no camera attached and no recording in the --recordings folders");
  throw std::runtime_error("no camera attached (libcamera and V4L2 found none); name one with --camera "
                           "(a recording: --camera replay:DIR, or --recordings DIR; propcam cameras lists them)");
}

// The camera's stream as asked, or as the camera adjusted it (said on stderr).
void configure(capture::FrameSource& source, const CameraChoice& c) {
  capture::StreamConfig config = source.configuration();
  if (!c.format.empty()) {
    const auto f = capture::pixel_format_from_string(c.format);
    if (!f) throw std::invalid_argument("unknown pixel format " + c.format);
    config.pixel_format = *f;
  }
  if (!c.size.empty()) parse_bench_size(c.size, kMinSide, config.width, config.height);
  if (c.fps > 0) config.fps = c.fps;
  const capture::ConfigStatus status = source.configure(config);
  if (status == capture::ConfigStatus::Invalid) throw std::runtime_error("the camera cannot deliver the asked stream");
  if (status == capture::ConfigStatus::Adjusted)
    std::fprintf(stderr, "camera: stream adjusted to %s %dx%d at %.3g fps\n", capture::to_string(config.pixel_format).c_str(),
                 config.width, config.height, config.fps);
}

capture::Frame take_frame(capture::FrameSource& source) {
  const capture::CaptureResult r = source.next_frame(kFrameTimeout);
  if (r.status != CaptureStatus::Ok || !r.frame)
    throw std::runtime_error("camera: " + capture::to_string(r.status) + (r.message.empty() ? "" : ": " + r.message));
  return *r.frame;
}

// The frames of a still photo as a camera in `format` would deliver them:
// packed by the real conversion code, with a little seeded sensor noise so
// consecutive frames differ as a live camera's do.
std::vector<capture::Frame> frames_from_photo(const RecordArgs& a) {
  cv::Mat rgb8 = capture::linear_to_srgb8(capture::load_photo_linear(a.from_photo));
  if (!a.choice.size.empty()) {
    int w = 0, h = 0;
    parse_bench_size(a.choice.size, kMinSide, w, h);
    cv::resize(rgb8, rgb8, {w, h}, 0, 0, cv::INTER_AREA);
  }
  capture::FrameFormat format;
  const auto f = capture::pixel_format_from_string(a.choice.format.empty() ? "YUYV" : a.choice.format);
  if (!f) throw std::invalid_argument("unknown pixel format " + a.choice.format);
  format.pixel_format = *f;
  format.width = rgb8.cols;
  format.height = rgb8.rows;
  format.stride = capture::minimum_stride(format.pixel_format, format.width);
  const double fps = a.choice.fps > 0 ? a.choice.fps : 30.0;
  std::mt19937 rng(1);
  std::vector<capture::Frame> frames;
  for (int i = 0; i < a.frames; ++i) {
    cv::Mat noisy;
    cv::Mat noise(rgb8.size(), CV_32FC3);
    cv::theRNG().state = rng();
    cv::randn(noise, 0.0, a.noise);
    rgb8.convertTo(noisy, CV_32FC3);
    noisy += noise;
    noisy.convertTo(noisy, CV_8UC3);  // saturating
    capture::Frame frame = capture::rgb8_to_frame(noisy, format);
    frame.metadata.sequence = static_cast<uint64_t>(i);
    frame.metadata.timestamp_ns = static_cast<int64_t>(i * 1e9 / fps);
    frames.push_back(std::move(frame));
  }
  return frames;
}

json latency_json(const capture::LatencyStats& l) {
  return {{"mean_ms", l.mean_ms}, {"p95_ms", l.p95_ms}, {"max_ms", l.max_ms}};
}

json daemon_run_json(const std::string& pacing, const capture::DaemonBenchResult& r) {
  return {{"pacing", pacing}, {"frames", r.frames_received}, {"seconds", r.seconds}, {"fps", r.fps},
          {"latency_ms", r.total.mean_ms}, {"latency", latency_json(r.total)}, {"source_latency", latency_json(r.source)},
          {"daemon_latency", latency_json(r.daemon)}, {"frames_captured", r.frames_captured},
          {"frames_dropped", r.frames_dropped}, {"sequence_gaps", r.sequence_gaps}, {"stopped_because", r.stopped_because}};
}

}  // namespace

std::string bundled_recordings_dir() {
  if (const char* env = std::getenv("PROPCAM_RECORDINGS")) return env;
  return (inference::data_dir() / "board" / "virtual" / "recordings").string();
}

void add_cameras_options(CLI::App& cmd, CamerasArgs& a) {
  cmd.add_option("--recordings", a.recordings, "Folders of recordings (default: the virtual board's)");
  cmd.add_flag("--json", a.json_out, "Machine-readable output");
}

int run_cameras_command(const CamerasArgs& a) {
  const auto cameras = capture::list_cameras(recordings_or_bundled(a.recordings));
  json out = json::array();
  for (const auto& c : cameras) out.push_back(camera_json(c));
  if (a.json_out) {
    std::cout << out.dump(2) << std::endl;
    return 0;
  }
  if (cameras.empty()) std::cout << "no cameras" << std::endl;
  for (size_t i = 0; i < cameras.size(); ++i) {
    std::cout << i << " : " << cameras[i].id << " (" << cameras[i].description << ")\n";
    for (const auto& f : out[i]["formats"]) {
      std::cout << "      " << f["format"].get<std::string>() << ":";
      for (const auto& s : f["sizes"]) std::cout << " " << s.get<std::string>();
      std::cout << "\n";
    }
  }
  std::cout << std::flush;
  return 0;
}

void add_record_options(CLI::App& cmd, RecordArgs& a) {
  add_camera_choice(cmd, a.choice);
  cmd.add_option("--from-photo", a.from_photo, "Pack a still photo as camera frames instead (the virtual camera)")
      ->check(CLI::ExistingFile);
  cmd.add_option("--noise", a.noise, "Sensor noise of --from-photo frames, 8-bit levels")->check(CLI::Range(0.0, 64.0));
  cmd.add_option("--frames", a.frames, "Frames to record")->check(CLI::Range(1, 100000));
  cmd.add_option("-o,--output", a.out, "Recording folder to write")->required();
  cmd.add_flag("--json", a.json_out, "Machine-readable output");
}

int run_record_command(const RecordArgs& a) {
  std::string id, description;
  std::vector<capture::Frame> photo_frames;
  std::unique_ptr<capture::FrameSource> source;
  if (!a.from_photo.empty()) {
    photo_frames = frames_from_photo(a);
    id = "photo:" + std::filesystem::path(a.from_photo).filename().string();
    description = "still photo packed by propcam record";
  } else {
    id = default_camera(a.choice);
    source = capture::open_camera(id);
    configure(*source, a.choice);
    description = source->info().description;
    source->start();
  }
  capture::Recorder recorder(a.out, id, description);
  for (int i = 0; i < a.frames; ++i) recorder.append(source ? take_frame(*source) : photo_frames[static_cast<size_t>(i)]);
  if (source) source->stop();
  const capture::Recording& r = recorder.finish();
  const json out = {{"recording", a.out}, {"camera", id}, {"frames", r.frames.size()},
                    {"format", capture::to_string(r.format.pixel_format)}, {"size", {r.format.width, r.format.height}},
                    {"bytes", r.total_bytes()}};
  if (a.json_out)
    std::cout << out.dump(2) << std::endl;
  else
    std::fprintf(stderr, "recorded %zu %s frames %dx%d from %s to %s\n", r.frames.size(),
                 capture::to_string(r.format.pixel_format).c_str(), r.format.width, r.format.height, id.c_str(), a.out.c_str());
  return 0;
}

void add_shoot_options(CLI::App& cmd, ShootArgs& a) {
  add_camera_choice(cmd, a.choice);
  cmd.add_option("--daemon", a.daemon_socket, "Shoot through propcamd at this socket instead of opening the camera");
  cmd.add_option("--still-size", a.still_size, "Still size WxH (default: the largest the camera offers)");
  cmd.add_option("--settle-frames", a.settle_frames, "Viewfinder frames before the shot")->check(CLI::Range(0, 1000));
  cmd.add_option("--exposure-us", a.exposure_us, "Manual exposure time, microseconds")->check(CLI::PositiveNumber);
  cmd.add_option("--gain", a.gain, "Manual analogue gain")->check(CLI::PositiveNumber);
  cmd.add_option("-o,--output", a.out, "Image to write (PNG, JPEG, EXR, ...)")->required();
  cmd.add_flag("--json", a.json_out, "Machine-readable output");
}

int run_shoot_command(const ShootArgs& a) {
  std::unique_ptr<capture::FrameSource> source;
  std::string id;
  if (!a.daemon_socket.empty()) {
    source = std::make_unique<capture::DaemonFrameSource>(
        a.daemon_socket, a.choice.camera.empty() ? std::nullopt : std::optional<std::string>(a.choice.camera));
    id = source->info().id;
  } else {
    id = default_camera(a.choice);
    source = capture::open_camera(id);
  }
  configure(*source, a.choice);
  source->start();
  for (int i = 0; i < a.settle_frames; ++i) take_frame(*source);
  // The shot keeps the exposure the viewfinder settled on (or the manual one).
  capture::CameraControls lock;
  lock.auto_exposure = false;
  if (a.exposure_us > 0) lock.exposure_us = a.exposure_us;
  if (a.gain > 0) lock.analogue_gain = a.gain;
  const std::vector<std::string> unapplied = source->set_controls(lock);
  std::optional<capture::StreamConfig> still;
  if (!a.still_size.empty()) {
    still = source->configuration();
    parse_bench_size(a.still_size, kMinSide, still->width, still->height);
  }
  const capture::CaptureResult r = source->capture_still(still, kStillTimeout);
  source->stop();
  if (r.status != CaptureStatus::Ok || !r.frame)
    throw std::runtime_error("shoot: " + capture::to_string(r.status) + (r.message.empty() ? "" : ": " + r.message));
  capture::write_image(a.out, capture::frame_to_rgb8(*r.frame));
  const capture::Frame& f = *r.frame;
  json out = {{"camera", id}, {"output", a.out}, {"format", capture::to_string(f.format.pixel_format)},
              {"size", {f.format.width, f.format.height}}, {"sequence", f.metadata.sequence},
              {"controls_not_applied", unapplied}};
  if (f.metadata.exposure_us) out["exposure_us"] = *f.metadata.exposure_us;
  if (f.metadata.analogue_gain) out["analogue_gain"] = *f.metadata.analogue_gain;
  if (a.json_out)
    std::cout << out.dump(2) << std::endl;
  else
    std::fprintf(stderr, "shot %dx%d %s from %s -> %s\n", f.format.width, f.format.height,
                 capture::to_string(f.format.pixel_format).c_str(), id.c_str(), a.out.c_str());
  return 0;
}

void add_bench_capture_options(CLI::App& cmd, CaptureBenchArgs& a) {
  cmd.add_option("--recording", a.recording, "Recording folder (default: the virtual board's first)");
  cmd.add_option("--frames", a.frames, "Frames per run")->check(CLI::Range(10, 100000));
  cmd.add_flag("--json", a.json_out, "Machine-readable output (fps and latency_ms of the paced run at top level)");
}

int run_bench_capture_command(const CaptureBenchArgs& a) {
  std::string recording = a.recording;
  if (recording.empty()) {
    for (const auto& c : capture::list_cameras({bundled_recordings_dir()}))
      if (c.backend == "replay" && !c.formats.empty()) {
        recording = c.id.substr(std::string("replay:").size());
        break;
      }
    if (recording.empty()) throw std::runtime_error("bench capture: no recording in " + bundled_recordings_dir());
  }
  const capture::Recording rec = capture::load_recording(recording);
  capture::DaemonBenchOptions options;
  options.camera_id = "replay:" + recording;
  options.stream = capture::StreamConfig{rec.format.pixel_format, rec.format.width, rec.format.height, 0};
  options.frames = a.frames;
  json runs = json::array();
  for (const auto pacing : {capture::ReplayPacing::Realtime, capture::ReplayPacing::AsFastAsPossible}) {
    const capture::FrameSourceFactory factory = [recording, pacing](const std::string&) {
      return std::make_unique<capture::ReplaySource>(recording, capture::ReplayOptions{true, pacing});
    };
    const std::string name = pacing == capture::ReplayPacing::Realtime ? "as recorded" : "as fast as possible";
    runs.push_back(daemon_run_json(name, capture::measure_daemon_throughput(factory, options)));
  }
  json out = {{"recording", recording}, {"format", capture::to_string(rec.format.pixel_format)},
              {"size", {rec.format.width, rec.format.height}}, {"fps", runs[0]["fps"]},
              {"latency_ms", runs[0]["latency_ms"]}, {"runs", runs}};
  if (a.json_out) {
    std::cout << out.dump(2) << std::endl;
    return 0;
  }
  std::printf("capture through propcamd: %s %dx%d from %s\n", capture::to_string(rec.format.pixel_format).c_str(),
              rec.format.width, rec.format.height, recording.c_str());
  std::printf("| pacing | frames | fps | latency mean / p95 ms | of which daemon mean / p95 ms | dropped |\n|---|---|---|---|---|---|\n");
  for (const auto& r : runs)
    std::printf("| %s | %d | %.1f | %.2f / %.2f | %.2f / %.2f | %llu |\n", r["pacing"].get<std::string>().c_str(),
                r["frames"].get<int>(), r["fps"].get<double>(), r["latency"]["mean_ms"].get<double>(),
                r["latency"]["p95_ms"].get<double>(), r["daemon_latency"]["mean_ms"].get<double>(),
                r["daemon_latency"]["p95_ms"].get<double>(),
                static_cast<unsigned long long>(r["frames_dropped"].get<uint64_t>()));
  return 0;
}

void add_calibrate_vignetting_options(CLI::App& cmd, CalibrateVignettingArgs& a) {
  cmd.add_option("frames", a.frames,
                 "Flat-field photos at the camera's still framing: an evenly lit white card filling the frame, or a "
                 "diffuser over the lens (several are averaged)")
      ->required();
  cmd.add_flag("--json", a.json_out, "Machine-readable result on stdout");
}

int run_calibrate_vignetting_command(const CalibrateVignettingArgs& a) {
  std::vector<cv::Mat> frames;
  for (const std::string& path : a.frames) frames.push_back(capture::load_photo_linear(path));
  const render::VignettingFit fit = render::fit_vignetting(frames);
  const render::Vignetting& v = fit.vignetting;
  if (a.json_out) {
    const json out = {{"r2", v.r2},
                      {"r4", v.r4},
                      {"corner_gain", v.at_radius(1.0)},
                      {"half_radius_gain", v.at_radius(0.5)},
                      {"residual_rms", fit.residual_rms},
                      {"light_gradient", fit.gradient},
                      {"pixels", fit.pixels},
                      {"frames", a.frames.size()}};
    std::printf("%s\n", out.dump(2).c_str());
    return 0;
  }
  std::printf("vignetting: r2 %.4f, r4 %.4f: gain %.3f in the corners, %.3f at half the radius\n", v.r2, v.r4,
              v.at_radius(1.0), v.at_radius(0.5));
  std::printf("fit: %d px of %zu frame(s) reduced; %.2f%% of log luminance left; the light's own gradient %.3f taken out\n",
              fit.pixels, a.frames.size(), 100.0 * fit.residual_rms, fit.gradient);
  std::printf("board.json, in \"camera\": \"vignetting\": {\"r2\": %.4f, \"r4\": %.4f}\n", v.r2, v.r4);
  std::printf("propcam composite: --vignetting=%.4f,%.4f\n", v.r2, v.r4);
  return 0;
}

}  // namespace propcam::firmware
