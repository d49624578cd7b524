#include "appliance/appliance_jobs.h"

#include <sys/resource.h>
#include <unistd.h>

#include <spdlog/spdlog.h>

namespace propcam::firmware {

void EventQueue::push(appliance::Event event) {
  std::lock_guard lock(mutex_);
  events_.push_back(std::move(event));
}

std::optional<appliance::Event> EventQueue::pop() {
  std::lock_guard lock(mutex_);
  if (events_.empty()) return std::nullopt;
  appliance::Event e = std::move(events_.front());
  events_.pop_front();
  return e;
}

JobRunner::JobRunner(int niceness) { thread_ = std::thread([this, niceness] { loop(niceness); }); }

JobRunner::~JobRunner() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
    queue_.clear();
    if (running_cancel_) *running_cancel_ = true;
  }
  changed_.notify_all();
  thread_.join();
}

void JobRunner::run(appliance::JobId job, Work work) {
  {
    std::lock_guard lock(mutex_);
    queue_.push_back({job, std::move(work), std::make_shared<std::atomic<bool>>(false)});
  }
  changed_.notify_all();
}

void JobRunner::cancel(appliance::JobId job) {
  std::lock_guard lock(mutex_);
  std::erase_if(queue_, [job](const Job& j) { return j.id == job; });
  if (running_ == job && running_cancel_) *running_cancel_ = true;
}

bool JobRunner::idle() const {
  std::lock_guard lock(mutex_);
  return queue_.empty() && running_ == 0;
}

void JobRunner::wait_idle() const {
  std::unique_lock lock(mutex_);
  changed_.wait(lock, [this] { return stop_ || (queue_.empty() && running_ == 0); });
}

void JobRunner::loop(int niceness) {
  // Linux: a thread's nice value is its own, and threads it creates inherit it.
  if (niceness > 0 && setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), niceness) != 0)
    spdlog::debug("jobs: could not lower the worker's priority");
  std::unique_lock lock(mutex_);
  while (true) {
    changed_.wait(lock, [this] { return stop_ || !queue_.empty(); });
    if (stop_) return;
    Job job = std::move(queue_.front());
    queue_.pop_front();
    running_ = job.id;
    running_cancel_ = job.cancel;
    lock.unlock();
    try {
      job.work(*job.cancel);
    } catch (const std::exception& e) {
      spdlog::error("job {}: {}", job.id, e.what());
    }
    lock.lock();
    running_ = 0;
    running_cancel_.reset();
    changed_.notify_all();
  }
}

}  // namespace propcam::firmware
