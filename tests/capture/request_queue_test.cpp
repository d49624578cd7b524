#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "request_queue.h"

namespace propcam::capture::detail {
namespace {

// Jobs that write their name into `log` when run.
struct Recorder {
  std::vector<std::string> log;
  RequestQueue::Job job(std::string name) {
    return [this, name] { log.push_back(name); };
  }
};

// Pops and runs every job, each done before the next: the daemon's camera thread.
void run_all(RequestQueue& q) {
  while (auto next = q.pop()) {
    next->job();
    q.done(next->client);
  }
}

TEST(RequestQueue, LimitCountsQueuedAndRunningRequests) {
  Recorder r;
  RequestQueue q(3);
  EXPECT_EQ(q.limit(), 3u);
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(q.push(7, r.job("a")));
  EXPECT_FALSE(q.push(7, r.job("refused")));
  EXPECT_TRUE(q.push(8, r.job("b")));  // the limit is per client
  auto running = q.pop();
  ASSERT_TRUE(running);
  EXPECT_EQ(running->client, 7u);
  EXPECT_EQ(q.pending(7), 3u);  // two queued, one running
  EXPECT_FALSE(q.push(7, r.job("refused")));
  q.done(7);
  EXPECT_EQ(q.pending(7), 2u);
  EXPECT_TRUE(q.push(7, r.job("a")));
  run_all(q);
  EXPECT_EQ(std::count(r.log.begin(), r.log.end(), "refused"), 0);
  EXPECT_EQ(r.log.size(), 4u);  // the popped one was never run here
  EXPECT_TRUE(q.empty());
  EXPECT_THROW(RequestQueue(0), std::invalid_argument);
}

TEST(RequestQueue, ClientsTakeTurnsAndEachClientsRequestsKeepTheirOrder) {
  Recorder r;
  RequestQueue q(8);
  for (const char* n : {"a1", "a2", "a3", "a4"}) q.push(1, r.job(n));
  for (const char* n : {"b1", "b2"}) q.push(2, r.job(n));
  q.push(3, r.job("c1"));
  EXPECT_EQ(q.queued(), 7u);
  run_all(q);
  EXPECT_EQ(r.log, (std::vector<std::string>{"a1", "b1", "c1", "a2", "b2", "a3", "a4"}));
}

TEST(RequestQueue, ANewcomerGoesBeforeAClientServedMeanwhile) {
  Recorder r;
  RequestQueue q(8);
  for (const char* n : {"a1", "a2", "a3"}) q.push(1, r.job(n));
  auto first = q.pop();  // a1 runs; then b arrives behind the older a2 and a3
  q.push(2, r.job("b1"));
  first->job();
  q.done(first->client);
  run_all(q);
  EXPECT_EQ(r.log, (std::vector<std::string>{"a1", "b1", "a2", "a3"}));
}

TEST(RequestQueue, DroppingAClientDiscardsItsQueuedRequests) {
  Recorder r;
  RequestQueue q(8);
  for (const char* n : {"a1", "a2", "a3"}) q.push(1, r.job(n));
  q.push(2, r.job("b1"));
  auto running = q.pop();
  ASSERT_EQ(running->client, 1u);
  EXPECT_EQ(q.drop(1), 2u);  // a2, a3; a1 is running and ends on its own
  EXPECT_EQ(q.pending(1), 0u);
  EXPECT_EQ(q.queued(), 1u);
  running->job();
  q.done(1);  // ignored: the client is gone
  run_all(q);
  EXPECT_EQ(r.log, (std::vector<std::string>{"a1", "b1"}));
  EXPECT_EQ(q.drop(1), 0u);
  EXPECT_EQ(q.drop(99), 0u);
  EXPECT_TRUE(q.empty());
}

}  // namespace
}  // namespace propcam::capture::detail
