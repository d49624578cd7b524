// The daemon's bounds on what one client may make it do: camera commands
// queued per client, served in turn, dropped when their client leaves, and
// the idle timeout. The synthetic camera's stills wait at a gate the test
// opens, so what is queued when is known without timing.
#include <gtest/gtest.h>

#include "daemon_test_support.h"

namespace propcam::capture {
namespace {

using namespace std::chrono_literals;
using test::RawClient;
using test::TestWorld;
namespace proto = protocol;

constexpr std::uint64_t kFirstStill = 1'000'000;  // the test camera's first still's sequence number

// Stills wait at the gate until a test lets them through.
test::Daemon gated_daemon(const std::function<void(CaptureServerOptions&)>& tweak = {}) {
  return test::Daemon(tweak, 0, test::Daemon::Stills::Gated);
}

proto::Packet still_request(std::uint32_t rid) {
  proto::CaptureStillRequest req;
  req.timeout_ms = 20000;
  return proto::encode(rid, req);
}

// A connection that has its Welcome.
std::unique_ptr<RawClient> welcomed(const std::string& path) {
  auto c = std::make_unique<RawClient>(path);
  const auto w = test::receive_reply(*c);
  if (!w || w->closed || test::type_of(w->bytes) != proto::MessageType::Welcome)
    throw std::runtime_error("no welcome");
  return c;
}

struct Reply {
  proto::MessageType type = proto::MessageType::Error;
  std::uint32_t request_id = 0;
  std::string error;           // of an Error
  std::uint64_t sequence = 0;  // of a StillFrame
};

std::optional<Reply> next_reply(RawClient& c) {
  const auto p = test::receive_reply(c);
  if (!p || p->closed) return std::nullopt;
  const proto::Header h = proto::decode_header(p->bytes.data(), p->bytes.size());
  const proto::Payload payload = proto::payload_of(p->bytes.data(), p->bytes.size());
  Reply r{h.type, h.request_id, {}, 0};
  if (h.type == proto::MessageType::Error) r.error = proto::decode_error(payload);
  if (h.type == proto::MessageType::StillFrame) r.sequence = proto::decode_still_frame(payload).metadata.sequence;
  return r;
}

// Returns once the server has handled everything `c` sent before (it answers a client's packets in order).
void sync(RawClient& c) {
  constexpr std::uint32_t kSyncRid = 60000;
  ASSERT_TRUE(c.send(proto::encode(proto::MessageType::GetStatus, kSyncRid)));
  const auto r = next_reply(c);
  ASSERT_TRUE(r);
  ASSERT_EQ(r->type, proto::MessageType::Status);
  ASSERT_EQ(r->request_id, kSyncRid);
}

TEST(CaptureDaemonLimits, ARequestOverTheClientsLimitGetsAnErrorNamingIt) {
  auto d = gated_daemon();
  auto a = welcomed(d.path());
  const auto limit = static_cast<std::uint32_t>(kMaxRequestsPerClient);
  for (std::uint32_t rid = 1; rid <= limit + 1; ++rid) ASSERT_TRUE(a->send(still_request(rid)));
  // The stills wait at the gate: the first answer is the refusal.
  auto r = next_reply(*a);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->type, proto::MessageType::Error);
  EXPECT_EQ(r->request_id, limit + 1);
  EXPECT_EQ(r->error, "too many requests: at most " + std::to_string(limit) +
                          " camera commands queued or running per client");
  // One still done frees one place, and only one.
  d.world->allow_stills(1);
  r = next_reply(*a);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->type, proto::MessageType::StillFrame);
  EXPECT_EQ(r->request_id, 1u);
  ASSERT_TRUE(a->send(still_request(100)));
  ASSERT_TRUE(a->send(still_request(101)));
  r = next_reply(*a);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->type, proto::MessageType::Error);
  EXPECT_EQ(r->request_id, 101u);
  // The connection stays and every queued still is answered, in order.
  d.world->free_stills();
  std::vector<std::uint32_t> answered;
  for (std::uint32_t i = 0; i < limit; ++i) {
    r = next_reply(*a);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->type, proto::MessageType::StillFrame);
    answered.push_back(r->request_id);
  }
  std::vector<std::uint32_t> expected;
  for (std::uint32_t rid = 2; rid <= limit; ++rid) expected.push_back(rid);
  expected.push_back(100);
  EXPECT_EQ(answered, expected);
  const RequestCounts counts = d.server->request_counts();
  EXPECT_EQ(counts.run, limit + 1);
  EXPECT_EQ(counts.refused, 2u);
  EXPECT_EQ(counts.dropped, 0u);
}

TEST(CaptureDaemonLimits, TheQueuedRequestsOfAClientThatLeftAreNeverRun) {
  auto d = gated_daemon();
  {
    auto flood = welcomed(d.path());
    for (std::uint32_t rid = 1; rid <= static_cast<std::uint32_t>(kMaxRequestsPerClient); ++rid)
      ASSERT_TRUE(flood->send(still_request(rid)));
    ASSERT_NO_FATAL_FAILURE(sync(*flood));
    ASSERT_TRUE(test::eventually([&] { return d.world->started_stills() == 1; }));  // the first one runs
  }  // and the flooding client leaves
  const auto queued_behind = static_cast<std::uint64_t>(kMaxRequestsPerClient - 1);
  ASSERT_TRUE(test::eventually([&] { return d.server->request_counts().dropped == queued_behind; }));

  CaptureClient good(d.path());
  d.world->free_stills();
  const CaptureResult r = good.capture_still(std::nullopt, 20s);
  ASSERT_EQ(r.status, CaptureStatus::Ok) << r.message;
  // The camera took the flood's running still (its answer went nowhere), then this one.
  EXPECT_EQ(r.frame->metadata.sequence, kFirstStill + 1);
  EXPECT_EQ(d.world->taken_stills(), 2);
  const RequestCounts counts = d.server->request_counts();
  EXPECT_EQ(counts.run, 2u);
  EXPECT_EQ(counts.dropped, queued_behind);
  EXPECT_EQ(good.status().clients.size(), 1u);
}

TEST(CaptureDaemonLimits, ClientsTakeTurnsSoOnesStillGoesBeforeAFloodsLaterOnes) {
  auto d = gated_daemon();
  auto a = welcomed(d.path());
  auto b = welcomed(d.path());
  const auto limit = static_cast<std::uint32_t>(kMaxRequestsPerClient);
  for (std::uint32_t rid = 1; rid <= limit; ++rid) ASSERT_TRUE(a->send(still_request(rid)));
  ASSERT_NO_FATAL_FAILURE(sync(*a));
  ASSERT_TRUE(test::eventually([&] { return d.world->started_stills() == 1; }));  // a's first runs
  ASSERT_TRUE(b->send(still_request(1)));
  ASSERT_NO_FATAL_FAILURE(sync(*b));
  d.world->free_stills();

  const auto rb = next_reply(*b);
  ASSERT_TRUE(rb);
  ASSERT_EQ(rb->type, proto::MessageType::StillFrame);
  EXPECT_EQ(rb->sequence, kFirstStill + 1);  // right after the still that was running
  std::vector<std::uint64_t> a_sequences;
  for (std::uint32_t rid = 1; rid <= limit; ++rid) {
    const auto ra = next_reply(*a);
    ASSERT_TRUE(ra);
    ASSERT_EQ(ra->type, proto::MessageType::StillFrame);
    EXPECT_EQ(ra->request_id, rid);
    a_sequences.push_back(ra->sequence);
  }
  std::vector<std::uint64_t> expected{kFirstStill};
  for (std::uint64_t i = 2; i <= limit; ++i) expected.push_back(kFirstStill + i);
  EXPECT_EQ(a_sequences, expected);
}

TEST(CaptureDaemonLimits, AnIdleConnectionIsClosedAndFreesItsPlace) {
  constexpr auto kIdle = 300ms;
  auto d = gated_daemon([&](CaptureServerOptions& o) {
    o.max_clients = 2;
    o.idle_timeout = kIdle;
  });
  auto a = welcomed(d.path());
  auto b = welcomed(d.path());
  ASSERT_TRUE(a->send(still_request(1)));
  ASSERT_TRUE(b->send(still_request(1)));
  ASSERT_NO_FATAL_FAILURE(sync(*a));
  ASSERT_NO_FATAL_FAILURE(sync(*b));
  // Full: a third connection is turned away.
  RawClient third(d.path());
  const auto refused = next_reply(third);
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->error, "too many clients");
  EXPECT_TRUE(third.hung_up());
  // Waiting for its own still is not idleness, however long the still takes.
  std::this_thread::sleep_for(3 * kIdle);
  d.world->free_stills();
  for (RawClient* c : {a.get(), b.get()}) {
    const auto r = next_reply(*c);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->type, proto::MessageType::StillFrame);
  }
  // Answered (a first) and then silent while the daemon is full: told why, and closed.
  const auto closing = next_reply(*a);
  ASSERT_TRUE(closing);
  EXPECT_EQ(closing->error, "connection closed: idle for 300 ms");
  EXPECT_TRUE(a->hung_up());
  // Its place is free; and a newcomer at a full daemon takes the place of
  // whoever has been silent past the timeout.
  auto newcomer = welcomed(d.path());
  std::this_thread::sleep_for(2 * kIdle);
  EXPECT_NO_THROW(welcomed(d.path()));
  EXPECT_TRUE(b->hung_up());
  EXPECT_EQ(d.server->request_counts().dropped, 0u);
}

// Below the limit nobody is waiting for a place: a quiet client (an
// appliance rendering, its viewfinder stopped) keeps its connection.
TEST(CaptureDaemonLimits, ASilentClientKeepsItsPlaceWhileThereIsRoom) {
  constexpr auto kIdle = 200ms;
  auto d = gated_daemon([&](CaptureServerOptions& o) {
    o.max_clients = 3;
    o.idle_timeout = kIdle;
  });
  auto quiet = welcomed(d.path());
  auto other = welcomed(d.path());
  EXPECT_FALSE(quiet->hung_up(4 * kIdle));
  EXPECT_FALSE(other->hung_up(kIdle));
  // A third fills the daemon: now the silent two make room for a fourth.
  auto third = welcomed(d.path());
  EXPECT_NO_THROW(welcomed(d.path()));
  EXPECT_TRUE(quiet->hung_up());
}

}  // namespace
}  // namespace propcam::capture
