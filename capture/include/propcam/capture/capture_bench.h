// How fast propcamd hands frames to a client: a CaptureServer and a
// CaptureClient in this process over a real UNIX socket, the client taking
// (and at once releasing) frames for N frames or S seconds.
//
// Latency is measured on CLOCK_MONOTONIC. `total` is the client's receive
// time minus the frame's timestamp_ns (sensor end of frame, as the source
// reports it); `source` is when next_frame returned in the server minus
// timestamp_ns (the backend's own delivery: driver dequeue, decode ...);
// `daemon` is the client's receive time minus that return, i.e. what the
// daemon adds (ring copy, socket, wake-ups). The source's part is taken by
// wrapping each source the factory opens.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

#include "propcam/capture/capture_server.h"

namespace propcam::capture {

struct DaemonBenchOptions {
  std::string socket_path;  // empty: a socket in a fresh temporary folder
  std::string camera_id = "synthetic";
  StreamConfig stream{PixelFormat::YUYV, 640, 480, 30};
  int frames = 300;                       // stop after this many frames received (0: no limit)
  std::chrono::milliseconds duration{0};  // or after this long (0: no limit)
  std::chrono::milliseconds frame_timeout{5000};  // no frame for this long ends the run
};

struct LatencyStats {
  double mean_ms = 0;
  double p95_ms = 0;
  double max_ms = 0;
};

struct DaemonBenchResult {
  int frames_received = 0;
  double seconds = 0;
  double fps = 0;                    // frames received per second
  LatencyStats total;                // receive - timestamp_ns
  LatencyStats source;               // next_frame returned - timestamp_ns
  LatencyStats daemon;               // receive - next_frame returned
  std::uint64_t frames_captured = 0;  // by the server's camera
  std::uint64_t frames_dropped = 0;   // missed by the client (its slots held or socket full)
  std::uint64_t sequence_gaps = 0;    // frames the client saw skipped in the sequence
  std::string stopped_because;        // "frames", "duration", "timeout", "device lost", ...
};

// Runs until `frames` frames arrived or `duration` passed (whichever is set
// and comes first; at least one must be set). Throws on socket errors.
DaemonBenchResult measure_daemon_throughput(const FrameSourceFactory& factory, const DaemonBenchOptions& options);

// A still's latency for a well-behaved client while another client floods
// the daemon with still requests: both over real sockets to a server in this
// process. The flooding client keeps `flood_depth` requests sent and not yet
// answered (refused ones are sent again at once); the well-behaved one takes
// `stills` stills one after another. Each still takes `still_time` in the
// camera (the source is wrapped), as a real camera's does: it stops the
// viewfinder, reconfigures and lets exposure settle.
struct FloodBenchOptions {
  std::string socket_path;  // empty: a socket in a fresh temporary folder
  std::string camera_id = "synthetic";
  StreamConfig stream{PixelFormat::YUYV, 640, 480, 30};
  std::chrono::milliseconds still_time{100};
  int flood_depth = 64;
  int stills = 20;
  std::chrono::milliseconds still_timeout{600000};  // the well-behaved client's wait for one still
};

struct FloodBenchResult {
  int stills = 0;                     // taken by the well-behaved client
  LatencyStats latency;               // its request-to-still time
  std::uint64_t flood_stills = 0;     // flood requests answered with a still
  std::uint64_t flood_refused = 0;    // flood requests answered with an error
  double seconds = 0;
};

// Throws on socket errors and when a well-behaved still fails.
FloodBenchResult measure_still_latency_under_flood(const FrameSourceFactory& factory,
                                                   const FloodBenchOptions& options);

// A camera-free source for the bench: RGB24 / BGR24 / YUYV / UYVY / GREY /
// NV12 frames of a moving pattern, paced at the config's fps (0: as fast
// as it can), timestamped when each frame is made.
FrameSourceFactory synthetic_source_factory();

}  // namespace propcam::capture
