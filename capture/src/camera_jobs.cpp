#include "camera_jobs.h"

#include <utility>

namespace propcam::capture::detail {

bool CameraJobs::submit(std::uint32_t client, RequestQueue::Job job) {
  {
    std::lock_guard lock(mu_);
    if (!requests_.push(client, std::move(job))) {
      ++counts_.refused;
      return false;
    }
  }
  cv_.notify_one();
  return true;
}

void CameraJobs::done(std::uint32_t client) {
  std::lock_guard lock(mu_);
  requests_.done(client);
}

void CameraJobs::drop(std::uint32_t client) {
  std::lock_guard lock(mu_);
  counts_.dropped += requests_.drop(client);  // nobody to answer; a running one's reply goes nowhere
}

std::size_t CameraJobs::pending(std::uint32_t client) const {
  std::lock_guard lock(mu_);
  return requests_.pending(client);
}

void CameraJobs::nudge() {
  {
    std::lock_guard lock(mu_);
    nudged_ = true;
  }
  cv_.notify_one();
}

bool CameraJobs::run_or_wait(std::optional<Clock::time_point> until) {
  std::unique_lock lock(mu_);
  if (until && requests_.empty() && !nudged_ && !stopping_) {
    cv_.wait_until(lock, *until, [&] { return !requests_.empty() || nudged_ || stopping_; });
  }
  nudged_ = false;
  while (!stopping_) {
    auto next = requests_.pop();
    if (!next) break;
    ++counts_.run;
    lock.unlock();
    next->job();
    lock.lock();
    requests_.done(next->client);  // a no-op when the job answered (one job of a client runs at a time)
  }
  return !stopping_;
}

bool CameraJobs::request_stop() {
  {
    std::lock_guard lock(mu_);
    if (stopping_) return false;
    stopping_ = true;
  }
  cv_.notify_all();
  return true;
}

bool CameraJobs::stopping() const {
  std::lock_guard lock(mu_);
  return stopping_;
}

RequestCounts CameraJobs::counts() const {
  std::lock_guard lock(mu_);
  return counts_;
}

}  // namespace propcam::capture::detail
