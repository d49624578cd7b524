// The appliance's threads meet here: workers post results into an
// EventQueue that the UI loop drains, and one JobRunner thread runs the
// long jobs (analysis, rendering, export) one after the other, each with
// its own cancel flag, so the UI thread never waits on them.
#pragma once

#include <atomic>
#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "appliance/appliance_state.h"

namespace propcam::firmware {

class EventQueue {
 public:
  void push(appliance::Event event);
  std::optional<appliance::Event> pop();  // never blocks

 private:
  std::mutex mutex_;
  std::deque<appliance::Event> events_;
};

class JobRunner {
 public:
  using Work = std::function<void(const std::atomic<bool>& cancel)>;
  // `niceness` > 0 lowers the worker thread's priority (and that of the render
  // threads it starts), so the UI thread stays responsive on a busy device.
  explicit JobRunner(int niceness = 0);
  ~JobRunner();  // cancels everything and joins
  JobRunner(const JobRunner&) = delete;
  JobRunner& operator=(const JobRunner&) = delete;

  // Queues a job; jobs run in order. Exceptions escaping `work` are logged and dropped.
  void run(appliance::JobId job, Work work);
  // Cancels the job: dropped if still queued, its flag raised if running.
  void cancel(appliance::JobId job);
  bool idle() const;
  // Blocks until nothing is queued or running (tests, shutdown).
  void wait_idle() const;

 private:
  struct Job {
    appliance::JobId id = 0;
    Work work;
    std::shared_ptr<std::atomic<bool>> cancel;
  };
  void loop(int niceness);

  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;
  std::deque<Job> queue_;
  appliance::JobId running_ = 0;
  std::shared_ptr<std::atomic<bool>> running_cancel_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace propcam::firmware
