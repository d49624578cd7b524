// CaptureServer puts the daemon's pieces together: the listening socket,
// the clients and ring they share (ClientHub), the queue of camera commands
// (CameraJobs), the camera thread and the epoll thread (ConnectionLoop).
#include "propcam/capture/capture_server.h"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <mutex>
#include <stdexcept>
#include <thread>

#include "camera_jobs.h"
#include "camera_thread.h"
#include "client_hub.h"
#include "connection_loop.h"
#include "listening_socket.h"

namespace propcam::capture {

struct CaptureServer::Impl {
  Impl(FrameSourceFactory factory, CaptureServerOptions options)
      : opt(std::move(options)),
        jobs(static_cast<std::size_t>(opt.max_requests_per_client)),
        hub(opt, jobs),
        camera(std::move(factory), opt, hub, jobs),
        loop(opt, hub, jobs, camera) {
    hub.wake = [this] { loop.wake(); };
  }

  const CaptureServerOptions opt;
  detail::CameraJobs jobs;
  detail::ClientHub hub;
  detail::CameraThread camera;
  detail::ConnectionLoop loop;
  detail::ListeningSocket listener;
  std::thread camera_thread, loop_thread;
  std::atomic<bool> started = false;  // read by running() from any thread

  std::mutex life_mu;
  std::condition_variable life_cv;
  bool stopped = false;
};

namespace {

CaptureServerOptions checked(CaptureServerOptions options) {
  if (options.max_held_slots < 1 || options.ring_slots < 1) throw std::invalid_argument("ring and held slots must be >= 1");
  if (options.max_requests_per_client < 1) throw std::invalid_argument("max_requests_per_client must be >= 1");
  options.max_stalled_frames = std::max(1, options.max_stalled_frames);
  return options;
}

}  // namespace

CaptureServer::CaptureServer(FrameSourceFactory factory, CaptureServerOptions options) {
  if (!factory) throw std::invalid_argument("CaptureServer needs a camera factory");
  impl_ = std::make_unique<Impl>(std::move(factory), checked(std::move(options)));
}

CaptureServer::~CaptureServer() { stop(); }

void CaptureServer::start() {
  Impl& m = *impl_;
  if (m.started) throw std::logic_error("CaptureServer started twice");
  m.listener.bind(m.opt.socket_path, m.opt.socket_group, m.opt.log);
  m.loop.open(m.listener.fd());
  m.started = true;
  m.camera_thread = std::thread([&m] { m.camera.run(); });
  m.loop_thread = std::thread([&m] { m.loop.run(); });
}

void CaptureServer::stop() {
  Impl& m = *impl_;
  if (!m.jobs.request_stop()) return;
  if (m.loop.is_open()) m.loop.wake();
  if (m.camera_thread.joinable()) m.camera_thread.join();
  if (m.loop_thread.joinable()) m.loop_thread.join();
  {
    std::lock_guard lock(m.hub.mu);
    m.hub.clients.clear();
    m.hub.ring.reset();
  }
  m.listener.close();
  m.listener.remove_file();
  {
    std::lock_guard lock(m.life_mu);
    m.stopped = true;
  }
  m.life_cv.notify_all();
}

bool CaptureServer::running() const { return impl_->started && !impl_->jobs.stopping(); }

void CaptureServer::wait() {
  std::unique_lock lock(impl_->life_mu);
  impl_->life_cv.wait(lock, [&] { return impl_->stopped; });
}

protocol::Status CaptureServer::status() const { return impl_->hub.status_snapshot(0); }

RequestCounts CaptureServer::request_counts() const { return impl_->jobs.counts(); }

const std::string& CaptureServer::socket_path() const { return impl_->opt.socket_path; }

}  // namespace propcam::capture
