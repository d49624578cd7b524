#include <gtest/gtest.h>

#include <signal.h>
#include <sys/mman.h>
#include <sys/wait.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <future>
#include <limits>

#include "daemon_test_support.h"

namespace propcam::capture {
namespace {

using namespace std::chrono_literals;
using test::Daemon;
using test::intact;
using test::RawClient;
using test::TestWorld;
namespace proto = protocol;

void round_trip(CaptureClient& c) { (void)c.status(); }

// A packet with a correct header around arbitrary payload bytes.
std::vector<std::uint8_t> packet(proto::MessageType type, std::uint32_t rid, const std::vector<std::uint8_t>& payload) {
  std::vector<std::uint8_t> p = proto::encode(type, rid);
  p.insert(p.end(), payload.begin(), payload.end());
  const auto size = static_cast<std::uint32_t>(payload.size());
  std::memcpy(p.data() + 8, &size, 4);
  return p;
}

template <typename T>
void append(std::vector<std::uint8_t>& v, T x) {
  const auto* b = reinterpret_cast<const std::uint8_t*>(&x);
  v.insert(v.end(), b, b + sizeof x);
}

// The good client still gets an intact frame.
void still_serves(Daemon& d, CaptureClient& good) {
  round_trip(good);
  d.world->allow(1);
  const CaptureResult r = test::next_non_timeout(good);
  ASSERT_EQ(r.status, CaptureStatus::Ok);
  EXPECT_TRUE(intact(*r.frame));
}

TEST(CaptureDaemonHardCases, BrokenFramingGetsAnErrorAndADisconnect) {
  Daemon d;
  CaptureClient good(d.path());
  good.start_viewfinder();
  std::vector<std::vector<std::uint8_t>> broken;
  broken.push_back(std::vector<std::uint8_t>(40, 0xab));  // no magic
  broken.push_back({1, 2, 3, 4, 5});                      // shorter than a header
  {
    auto p = proto::encode(proto::MessageType::GetStatus, 7);
    p.push_back(0);
    std::uint32_t lie = 100;
    std::memcpy(p.data() + 8, &lie, 4);  // payload size that does not match
    broken.push_back(p);
  }
  {
    auto p = proto::encode(proto::MessageType::GetStatus, 7);
    std::uint16_t type = 55;
    std::memcpy(p.data() + 6, &type, 2);  // unknown type
    broken.push_back(p);
  }
  {
    auto p = proto::encode(proto::MessageType::GetStatus, 7);
    std::uint16_t version = 2;
    std::memcpy(p.data() + 4, &version, 2);
    broken.push_back(p);
  }
  broken.push_back(packet(proto::MessageType::SelectCamera, 7, std::vector<std::uint8_t>(70000, 1)));  // oversized
  for (const auto& bytes : broken) {
    RawClient raw(d.path());
    ASSERT_TRUE(raw.receive());  // Welcome
    ASSERT_TRUE(raw.send(bytes));
    auto reply = test::receive_reply(raw);
    ASSERT_TRUE(reply && !reply->closed) << bytes.size();
    EXPECT_EQ(test::type_of(reply->bytes), proto::MessageType::Error);
    EXPECT_TRUE(raw.hung_up());
  }
  {
    RawClient raw(d.path());  // an empty packet reads as a hang-up
    ASSERT_TRUE(raw.receive());
    ASSERT_TRUE(raw.send({}));
    EXPECT_TRUE(raw.hung_up());
  }
  still_serves(d, good);
  ASSERT_TRUE(test::eventually([&] { return good.status().clients.size() == 1; }));
}

TEST(CaptureDaemonHardCases, BadPayloadsGetAnErrorAndTheConnectionStays) {
  Daemon d;
  CaptureClient good(d.path());
  good.start_viewfinder();
  RawClient raw(d.path());
  auto welcome_packet = raw.receive();
  ASSERT_TRUE(welcome_packet && !welcome_packet->closed);
  const proto::Welcome welcome =
      proto::decode_welcome(proto::payload_of(welcome_packet->bytes.data(), welcome_packet->bytes.size()));
  ASSERT_TRUE(welcome.ring);  // the camera was open before we connected
  const std::uint32_t generation = welcome.ring->generation;

  std::vector<std::vector<std::uint8_t>> bad;
  {
    std::vector<std::uint8_t> p;
    append<std::uint8_t>(p, 99);  // pixel format out of range
    append<std::int32_t>(p, 64);
    append<std::int32_t>(p, 48);
    append<double>(p, 30);
    bad.push_back(packet(proto::MessageType::Configure, 11, p));
  }
  {
    std::vector<std::uint8_t> p;
    append<std::uint8_t>(p, 0);
    append<std::int32_t>(p, -5);  // negative width
    append<std::int32_t>(p, 48);
    append<double>(p, 30);
    bad.push_back(packet(proto::MessageType::Configure, 12, p));
  }
  {
    std::vector<std::uint8_t> p;
    append<std::uint32_t>(p, 0xffffffffu);  // string longer than the packet
    p.push_back('x');
    bad.push_back(packet(proto::MessageType::SelectCamera, 13, p));
  }
  bad.push_back(packet(proto::MessageType::SetControls, 14, {1}));  // exposure "present", no value
  {
    std::vector<std::uint8_t> p;
    append<std::uint8_t>(p, 1);
    append<double>(p, std::numeric_limits<double>::quiet_NaN());
    for (int i = 0; i < 5; ++i) append<std::uint8_t>(p, 0);
    bad.push_back(packet(proto::MessageType::SetControls, 15, p));
  }
  {
    std::vector<std::uint8_t> p;
    append<std::uint32_t>(p, generation);
    append<std::uint32_t>(p, 9999);  // no such slot
    bad.push_back(packet(proto::MessageType::ReleaseSlot, 16, p));
  }
  {
    std::vector<std::uint8_t> p;
    append<std::uint32_t>(p, generation);
    append<std::uint32_t>(p, 0);  // a slot this client does not hold
    bad.push_back(packet(proto::MessageType::ReleaseSlot, 17, p));
  }
  bad.push_back(packet(proto::MessageType::Welcome, 18, {0, 0, 0, 0, 0, 0, 0, 0, 0}));  // a server message
  bad.push_back(packet(proto::MessageType::GetStatus, 19, {0}));                        // trailing byte
  bad.push_back(packet(proto::MessageType::CaptureStill, 20, {7, 0, 0, 0, 0}));         // bool of 7
  {
    std::vector<std::uint8_t> p;
    append<std::uint8_t>(p, 0);
    append<std::uint32_t>(p, 3'600'000);  // an hour-long still timeout
    bad.push_back(packet(proto::MessageType::CaptureStill, 21, p));
  }
  for (const auto& bytes : bad) {
    ASSERT_TRUE(raw.send(bytes));
    auto reply = test::receive_reply(raw);
    ASSERT_TRUE(reply && !reply->closed);
    const proto::Header h = proto::decode_header(reply->bytes.data(), reply->bytes.size());
    EXPECT_EQ(h.type, proto::MessageType::Error);
    std::uint32_t rid;
    std::memcpy(&rid, bytes.data() + 12, 4);
    EXPECT_EQ(h.request_id, rid);
  }
  ASSERT_TRUE(raw.send(proto::encode(proto::MessageType::GetStatus, 30)));
  auto status = test::receive_reply(raw);
  ASSERT_TRUE(status && !status->closed);
  EXPECT_EQ(test::type_of(status->bytes), proto::MessageType::Status);
  still_serves(d, good);
}

int open_fds() {
  int n = 0;
  for (const auto& e : std::filesystem::directory_iterator("/proc/self/fd")) {
    (void)e;
    ++n;
  }
  return n;
}

TEST(CaptureDaemonHardCases, FdsAClientSendsAreClosed) {
  Daemon d;
  RawClient raw(d.path());
  ASSERT_TRUE(raw.receive());
  ASSERT_TRUE(raw.send(proto::encode(proto::MessageType::GetStatus, 1)));
  ASSERT_TRUE(raw.receive());
  const int before = open_fds();
  for (std::uint32_t i = 0; i < 50; ++i) {
    const int fd = ::memfd_create("junk", MFD_CLOEXEC);
    ASSERT_GE(fd, 0);
    ASSERT_TRUE(raw.send(proto::encode(proto::MessageType::GetStatus, 100 + i), fd));
    ::close(fd);
    auto reply = raw.receive();
    ASSERT_TRUE(reply && !reply->closed);
  }
  EXPECT_EQ(open_fds(), before);
}

TEST(CaptureDaemonHardCases, ClientThatNeverReadsIsDropped) {
  Daemon d;
  CaptureClient good(d.path());
  good.start_viewfinder();
  RawClient spammer(d.path());
  // Requests without ever reading a reply: the server cannot queue the
  // replies without bound, so it lets the client go.
  bool refused = false;
  for (int i = 0; i < 200000 && !refused; ++i) {
    const auto p = proto::encode(proto::MessageType::GetStatus, static_cast<std::uint32_t>(i + 1));
    if (::send(spammer.fd(), p.data(), p.size(), MSG_NOSIGNAL | MSG_DONTWAIT) < 0) {
      if (errno == EAGAIN) {
        pollfd pf{spammer.fd(), POLLOUT, 0};
        ::poll(&pf, 1, 100);
        continue;
      }
      refused = true;  // EPIPE / ECONNRESET: dropped
    }
  }
  EXPECT_TRUE(refused || spammer.hung_up());
  still_serves(d, good);
  ASSERT_TRUE(test::eventually([&] { return good.status().clients.size() == 1; }));
}

TEST(CaptureDaemonHardCases, FrameReaderWhoseSocketFillsIsDropped) {
  // Slots enough that the socket fills before the hold limit: frames then
  // fail with EAGAIN, are missed, and after max_stalled_frames the client goes.
  auto log = std::make_shared<std::pair<std::mutex, std::vector<std::string>>>();
  Daemon d(
      [&](CaptureServerOptions& o) {
        o.ring_slots = 1024;
        o.max_held_slots = 1000;
        o.max_stalled_frames = 8;
        o.log = [log](const std::string& line) {
          std::lock_guard lock(log->first);
          log->second.push_back(line);
        };
      },
      0);
  CaptureClient good(d.path());
  good.start_viewfinder();
  RawClient stalled(d.path());
  ASSERT_TRUE(stalled.receive());
  ASSERT_TRUE(stalled.send(proto::encode(proto::MessageType::StartViewfinder, 1)));
  // Frame by frame, so the good client keeps up (a free-running camera
  // would fill its socket too, with 1000 frames allowed in flight).
  bool stalled_gone = false;
  for (int i = 0; i < 20000 && !stalled_gone; ++i) {
    round_trip(good);
    d.world->allow(1);
    const CaptureResult r = test::next_non_timeout(good);
    ASSERT_EQ(r.status, CaptureStatus::Ok);
    EXPECT_TRUE(intact(*r.frame));
    stalled_gone = good.status().clients.size() == 1;
  }
  EXPECT_TRUE(stalled_gone);
  EXPECT_TRUE(stalled.hung_up());
  const auto me = test::find_client(good.status(), good.client_id());
  ASSERT_TRUE(me);
  EXPECT_EQ(me->frames_dropped, 0u);
  {
    std::lock_guard lock(log->first);
    EXPECT_TRUE(std::any_of(log->second.begin(), log->second.end(),
                            [](const std::string& l) { return l.find("stopped reading") != std::string::npos; }));
  }
}

TEST(CaptureDaemonHardCases, CameraNeverWaitsForClients) {
  Daemon d({}, -1);  // free-running camera
  CaptureClient slow(d.path());
  slow.start_viewfinder();  // holds two frames, never reads again
  RawClient silent(d.path());
  ASSERT_TRUE(silent.receive());
  ASSERT_TRUE(silent.send(proto::encode(proto::MessageType::StartViewfinder, 1)));
  const std::uint64_t start = d.world->produced();
  ASSERT_TRUE(test::eventually([&] { return d.world->produced() >= start + 500; }));
  CaptureClient fresh(d.path());
  fresh.start_viewfinder();
  for (int i = 0; i < 5; ++i) {
    const CaptureResult r = test::next_non_timeout(fresh);
    ASSERT_EQ(r.status, CaptureStatus::Ok);
    EXPECT_TRUE(intact(*r.frame));
  }
  const auto s = test::find_client(fresh.status(), slow.client_id());
  ASSERT_TRUE(s);
  EXPECT_EQ(s->frames_sent, 2u);
  EXPECT_GE(s->frames_dropped, 498u);
}

TEST(CaptureDaemonHardCases, KilledClientProcessFreesItsSlots) {
  Daemon d([](CaptureServerOptions& o) { o.ring_slots = 2; });
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    int code = 1;
    try {
      CaptureClient c(d.options.socket_path);
      c.start_viewfinder();
      CaptureResult a = test::next_non_timeout(c), b = test::next_non_timeout(c);
      if (a.status == CaptureStatus::Ok && b.status == CaptureStatus::Ok) {
        const char byte = 1;
        if (::write(ready[1], &byte, 1) == 1) ::pause();  // holding both slots until killed
      }
    } catch (...) {
    }
    ::_exit(code);
  }
  ::close(ready[1]);
  d.world->allow(2);
  pollfd p{ready[0], POLLIN, 0};
  ASSERT_EQ(::poll(&p, 1, 20000), 1);
  ::kill(child, SIGKILL);
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ::close(ready[0]);
  CaptureClient c(d.path());
  ASSERT_TRUE(test::eventually([&] { return c.status().clients.size() == 1; }));
  c.start_viewfinder();
  d.world->allow(1);
  const CaptureResult r = test::next_non_timeout(c);
  ASSERT_EQ(r.status, CaptureStatus::Ok);
  EXPECT_EQ(r.frame->metadata.sequence, 2u);
  EXPECT_EQ(c.status().frames_unplaced, 0u);
}

TEST(CaptureDaemonHardCases, ClientsComingAndGoingDoNotDisturbOthers) {
  Daemon d({}, -1);
  CaptureClient steady(d.path());
  steady.start_viewfinder();
  std::atomic<bool> failed{false};
  std::vector<std::thread> churn;
  for (int t = 0; t < 3; ++t) {
    churn.emplace_back([&] {
      for (int i = 0; i < 15; ++i) {
        try {
          CaptureClient c(d.path());
          c.start_viewfinder();
          const CaptureResult r = c.next_frame(2s);
          if (r.status == CaptureStatus::Ok && !intact(*r.frame)) failed = true;
        } catch (const std::exception&) {
          failed = true;
        }
      }
    });
  }
  std::uint64_t last = 0;
  for (int i = 0; i < 100; ++i) {
    const CaptureResult r = test::next_non_timeout(steady);
    ASSERT_EQ(r.status, CaptureStatus::Ok);
    EXPECT_TRUE(intact(*r.frame));
    if (i > 0) {
      EXPECT_GT(r.frame->metadata.sequence, last);
    }
    last = r.frame->metadata.sequence;
  }
  for (auto& t : churn) t.join();
  EXPECT_FALSE(failed);
  ASSERT_TRUE(test::eventually([&] { return steady.status().clients.size() == 1; }));
}

TEST(CaptureDaemonHardCases, FrameOutlivesItsClient) {
  Daemon d;
  std::optional<Frame> kept;
  {
    CaptureClient c(d.path());
    c.start_viewfinder();
    d.world->allow(1);
    CaptureResult r = test::next_non_timeout(c);
    ASSERT_EQ(r.status, CaptureStatus::Ok);
    kept = std::move(r.frame);
  }
  EXPECT_TRUE(intact(*kept));  // the mapping and the connection live with the frame
  CaptureClient other(d.path());
  EXPECT_EQ(other.status().clients.size(), 2u);
  kept.reset();  // the last reference: slot released, connection closed
  ASSERT_TRUE(test::eventually([&] { return other.status().clients.size() == 1; }));
}

TEST(CaptureDaemonHardCases, FramesReleasedFromOtherThreads) {
  Daemon d({}, -1);
  CaptureClient c(d.path());
  c.start_viewfinder();
  std::vector<std::future<bool>> checks;
  for (int i = 0; i < 60; ++i) {
    CaptureResult r = test::next_non_timeout(c);
    ASSERT_EQ(r.status, CaptureStatus::Ok);
    auto frame = std::make_shared<Frame>(std::move(*r.frame));
    checks.push_back(std::async(std::launch::async, [frame]() mutable {
      const bool ok = intact(*frame);
      frame.reset();  // released on this thread
      return ok;
    }));
  }
  for (auto& f : checks) EXPECT_TRUE(f.get());
  const auto me = test::find_client(c.status(), c.client_id());
  ASSERT_TRUE(me);
  EXPECT_LE(me->slots_held, 2u);  // every slot given back but those of frames still queued
}

TEST(CaptureDaemonHardCases, EndOfRecordingIsAnEvent) {
  Daemon d({}, -1);
  d.world->end_after = 3;
  CaptureClient c(d.path());
  c.start_viewfinder();
  int frames = 0;
  CaptureResult r;
  for (;;) {
    r = test::next_non_timeout(c);
    if (r.status != CaptureStatus::Ok) break;
    ++frames;
  }
  EXPECT_EQ(r.status, CaptureStatus::EndOfStream);
  EXPECT_LE(frames, 3);
  EXPECT_EQ(c.device_state(), proto::DeviceState::Ended);
  EXPECT_EQ(c.status().device_state, proto::DeviceState::Ended);
}

TEST(CaptureDaemonHardCases, StoppingTheServerEndsTheClients) {
  Daemon d;
  CaptureClient c(d.path());
  c.start_viewfinder();
  d.server->stop();
  EXPECT_FALSE(d.server->running());
  const CaptureResult r = test::next_non_timeout(c);
  EXPECT_EQ(r.status, CaptureStatus::DeviceLost);
  EXPECT_FALSE(c.connected());
  EXPECT_THROW(c.status(), CaptureClientError);
  EXPECT_FALSE(std::filesystem::exists(d.path()));
  EXPECT_THROW(CaptureClient(d.path()), CaptureClientError);
}

TEST(CaptureDaemonHardCases, BadSocketPaths) {
  auto world = std::make_shared<TestWorld>();
  auto options = test::test_options(std::string(200, 'x'));
  CaptureServer too_long(test::test_factory(world), options);
  EXPECT_THROW(too_long.start(), std::runtime_error);

  const std::string file = test::temp_socket("not-a-socket");
  std::ofstream(file) << "precious";
  CaptureServer on_a_file(test::test_factory(world), test::test_options(file));
  EXPECT_THROW(on_a_file.start(), std::runtime_error);
  EXPECT_TRUE(std::filesystem::is_regular_file(file));  // never removed
}

TEST(CaptureDaemonHardCases, TooManyClientsAreTurnedAway) {
  Daemon d([](CaptureServerOptions& o) { o.max_clients = 2; });
  CaptureClient a(d.path()), b(d.path());
  EXPECT_THROW(CaptureClient(d.path()), CaptureClientError);
  EXPECT_EQ(a.status().clients.size(), 2u);
}

TEST(CaptureDaemonHardCases, CameraAbsentAtStartIsRetried) {
  auto world = std::make_shared<TestWorld>();
  world->fail_opens = 4;
  world->permits = 0;
  CaptureServer server(test::test_factory(world), test::test_options(test::temp_socket("capture.sock")));
  server.start();
  CaptureClient c(server.socket_path());
  ASSERT_TRUE(test::eventually([&] { return c.status().device_state == proto::DeviceState::Idle; }));
  c.start_viewfinder();
  world->allow(1);
  const CaptureResult r = test::next_non_timeout(c);
  ASSERT_EQ(r.status, CaptureStatus::Ok);
  EXPECT_TRUE(intact(*r.frame));
  std::lock_guard lock(world->mu);
  EXPECT_EQ(world->open_attempts, 5);
}

TEST(CaptureDaemonHardCases, HeldFrameSurvivesANewRing) {
  Daemon d;
  CaptureClient c(d.path());
  c.start_viewfinder();
  d.world->allow(1);
  CaptureResult held = test::next_non_timeout(c);
  ASSERT_EQ(held.status, CaptureStatus::Ok);
  StreamConfig big{PixelFormat::RGB24, 640, 480, 30};
  ASSERT_EQ(c.configure(big), ConfigStatus::Valid);  // larger frames: a new ring
  d.world->allow(2);
  for (int i = 0; i < 2; ++i) {
    const CaptureResult r = test::next_non_timeout(c);
    ASSERT_EQ(r.status, CaptureStatus::Ok);
    EXPECT_EQ(r.frame->format.width, 640);
    EXPECT_TRUE(intact(*r.frame));
    round_trip(c);
  }
  EXPECT_TRUE(intact(*held.frame));  // still the old ring's bytes
  EXPECT_EQ(held.frame->format.width, 64);
}

TEST(CaptureDaemonHardCases, ProtocolRoundTripsAndRejectsTruncation) {
  proto::Status s;
  s.camera_id = "v4l2:/dev/video0";
  s.stream = StreamConfig{PixelFormat::NV12, 1920, 1080, 29.97};
  s.device_state = proto::DeviceState::Lost;
  s.fps = 12.5;
  s.frames_captured = 1u << 20;
  s.clients.push_back(proto::ClientStatus{3, 10, 2, 1, true});
  const auto bytes = proto::encode(9, s);
  const proto::Header h = proto::decode_header(bytes.data(), bytes.size());
  EXPECT_EQ(h.request_id, 9u);
  const proto::Status back = proto::decode_status(proto::payload_of(bytes.data(), bytes.size()));
  EXPECT_EQ(back.camera_id, s.camera_id);
  EXPECT_EQ(back.stream.pixel_format, PixelFormat::NV12);
  EXPECT_DOUBLE_EQ(back.stream.fps, 29.97);
  EXPECT_EQ(back.device_state, proto::DeviceState::Lost);
  ASSERT_EQ(back.clients.size(), 1u);
  EXPECT_TRUE(back.clients[0].viewfinder);
  // Every truncation of the payload is refused, never read past.
  for (std::size_t n = proto::kHeaderBytes; n < bytes.size(); ++n)
    EXPECT_THROW(proto::decode_status(proto::Payload{bytes.data() + proto::kHeaderBytes, n - proto::kHeaderBytes}),
                 proto::ProtocolError);
}

}  // namespace
}  // namespace propcam::capture
