#include <gtest/gtest.h>

#include <grp.h>
#include <sys/stat.h>

#include <filesystem>

#include "daemon_test_support.h"
#include "propcam/capture/capture_bench.h"
#include "propcam/capture/replay_source.h"

namespace propcam::capture {
namespace {

using namespace std::chrono_literals;
using test::intact;
using test::Daemon;
using test::TestWorld;

// A request answered: the server has handled everything this client sent
// before, releases of the frames it dropped included. Without it the next
// frame can be offered before the release arrives, and be missed.
void round_trip(CaptureClient& c) { (void)c.status(); }

TEST(CaptureDaemon, FramesArriveIntactAndInOrder) {
  Daemon d;
  CaptureClient client(d.path());
  client.start_viewfinder();
  for (std::uint64_t i = 0; i < 40; ++i) {
    round_trip(client);
    d.world->allow(1);
    const CaptureResult r = test::next_non_timeout(client);
    ASSERT_EQ(r.status, CaptureStatus::Ok) << r.message;
    ASSERT_TRUE(r.frame);
    EXPECT_EQ(r.frame->metadata.sequence, i);
    EXPECT_EQ(r.frame->format.pixel_format, PixelFormat::RGB24);
    EXPECT_EQ(r.frame->format.width, 64);
    EXPECT_EQ(r.frame->bytes_used, 64u * 48u * 3u);
    EXPECT_TRUE(intact(*r.frame));
  }
  const protocol::Status s = client.status();
  EXPECT_EQ(s.camera_id, "test:a");
  EXPECT_EQ(s.device_state, protocol::DeviceState::Streaming);
  EXPECT_EQ(s.frames_captured, 40u);
  const auto me = test::find_client(s, client.client_id());
  ASSERT_TRUE(me);
  EXPECT_EQ(me->frames_sent, 40u);
  EXPECT_EQ(me->frames_dropped, 0u);
}

TEST(CaptureDaemon, TwoClientsGetTheSameFrames) {
  Daemon d;
  CaptureClient a(d.path()), b(d.path());
  EXPECT_NE(a.client_id(), b.client_id());
  a.start_viewfinder();
  b.start_viewfinder();
  for (std::uint64_t i = 0; i < 20; ++i) {
    round_trip(a);
    round_trip(b);
    d.world->allow(1);
    const CaptureResult ra = test::next_non_timeout(a);
    const CaptureResult rb = test::next_non_timeout(b);
    ASSERT_EQ(ra.status, CaptureStatus::Ok);
    ASSERT_EQ(rb.status, CaptureStatus::Ok);
    EXPECT_EQ(ra.frame->metadata.sequence, i);
    EXPECT_EQ(rb.frame->metadata.sequence, i);
    EXPECT_TRUE(intact(*ra.frame));
    EXPECT_TRUE(intact(*rb.frame));
    // One copy in the ring: both views show the same slot's bytes.
    EXPECT_TRUE(std::equal(ra.frame->data().begin(), ra.frame->data().end(), rb.frame->data().begin()));
  }
}

TEST(CaptureDaemon, SlowClientMissesFramesFastClientGetsEvery) {
  Daemon d;
  CaptureClient slow(d.path()), fast(d.path());
  slow.start_viewfinder();  // and never reads nor releases again
  fast.start_viewfinder();
  constexpr std::uint64_t kFrames = 60;
  for (std::uint64_t i = 0; i < kFrames; ++i) {
    round_trip(fast);
    d.world->allow(1);
    const CaptureResult r = test::next_non_timeout(fast);
    ASSERT_EQ(r.status, CaptureStatus::Ok);
    EXPECT_EQ(r.frame->metadata.sequence, i);
    EXPECT_TRUE(intact(*r.frame));
  }
  EXPECT_EQ(d.world->produced(), kFrames);  // the camera was never held back
  const protocol::Status s = fast.status();
  const auto fs = test::find_client(s, fast.client_id());
  const auto ss = test::find_client(s, slow.client_id());
  ASSERT_TRUE(fs && ss);
  EXPECT_EQ(fs->frames_sent, kFrames);
  EXPECT_EQ(fs->frames_dropped, 0u);
  EXPECT_EQ(ss->frames_sent, 2u);  // max_held_slots
  EXPECT_EQ(ss->slots_held, 2u);
  EXPECT_EQ(ss->frames_dropped, kFrames - 2);
  EXPECT_EQ(s.frames_unplaced, 0u);
}

TEST(CaptureDaemon, HeldFramesLimitIsPerClientAndReleasingResumes) {
  Daemon d;
  CaptureClient c(d.path());
  c.start_viewfinder();
  d.world->allow(2);
  CaptureResult first = test::next_non_timeout(c), second = test::next_non_timeout(c);
  ASSERT_EQ(first.status, CaptureStatus::Ok);
  ASSERT_EQ(second.status, CaptureStatus::Ok);
  d.world->allow(3);  // all missed: both slots held
  ASSERT_TRUE(test::eventually([&] { return d.world->produced() == 5; }));
  ASSERT_TRUE(test::eventually([&] {
    const auto me = test::find_client(c.status(), c.client_id());
    return me && me->frames_dropped == 3;
  }));
  first = CaptureResult{};  // releases one slot
  ASSERT_TRUE(test::eventually([&] {
    const auto me = test::find_client(c.status(), c.client_id());
    return me && me->slots_held == 1;
  }));
  d.world->allow(1);
  const CaptureResult next = test::next_non_timeout(c);
  ASSERT_EQ(next.status, CaptureStatus::Ok);
  EXPECT_EQ(next.frame->metadata.sequence, 5u);
  EXPECT_TRUE(intact(*next.frame));
}

TEST(CaptureDaemon, AbruptDisconnectFreesItsSlots) {
  // Two ring slots: if the vanished client's slots stayed taken no frame could be placed.
  Daemon d([](CaptureServerOptions& o) { o.ring_slots = 2; });
  {
    test::RawClient raw(d.path());
    ASSERT_TRUE(raw.receive());  // Welcome
    ASSERT_TRUE(raw.send(protocol::encode(protocol::MessageType::StartViewfinder, 1)));
    ASSERT_TRUE(raw.receive());  // Ok
    d.world->allow(2);
    int frames = 0;
    while (frames < 2) {
      auto p = raw.receive();
      ASSERT_TRUE(p && !p->closed);
      if (test::type_of(p->bytes) == protocol::MessageType::FrameReady) ++frames;
    }
    // Leaves without releasing or saying goodbye.
  }
  CaptureClient c(d.path());
  ASSERT_TRUE(test::eventually([&] { return c.status().clients.size() == 1; }));
  c.start_viewfinder();
  d.world->allow(1);
  const CaptureResult r = test::next_non_timeout(c);
  ASSERT_EQ(r.status, CaptureStatus::Ok);
  EXPECT_EQ(r.frame->metadata.sequence, 2u);
  EXPECT_TRUE(intact(*r.frame));
  EXPECT_EQ(c.status().frames_unplaced, 0u);
}

TEST(CaptureDaemon, DestroyedClientWithoutGoodbyeFreesItsSlots) {
  Daemon d([](CaptureServerOptions& o) { o.ring_slots = 2; });
  {
    CaptureClient gone(d.path());
    gone.start_viewfinder();
    d.world->allow(2);
    ASSERT_TRUE(test::eventually([&] { return d.world->produced() == 2; }));
    // Destroyed with both frames unread in its queue.
  }
  CaptureClient c(d.path());
  ASSERT_TRUE(test::eventually([&] { return c.status().clients.size() == 1; }));
  c.start_viewfinder();
  d.world->allow(1);
  const CaptureResult r = test::next_non_timeout(c);
  ASSERT_EQ(r.status, CaptureStatus::Ok);
  EXPECT_EQ(r.frame->metadata.sequence, 2u);
}

TEST(CaptureDaemon, DeviceLostThenResumed) {
  Daemon d;
  CaptureClient c(d.path());
  c.start_viewfinder();
  d.world->allow(1);
  ASSERT_EQ(test::next_non_timeout(c).status, CaptureStatus::Ok);
  const int attempts_before = [&] {
    std::lock_guard lock(d.world->mu);
    d.world->fail_opens = 3;  // the camera needs three retries to come back
    return d.world->open_attempts;
  }();
  d.world->pull_the_plug();
  const CaptureResult lost = test::next_non_timeout(c);
  EXPECT_EQ(lost.status, CaptureStatus::DeviceLost);
  EXPECT_NE(lost.message.find("unplugged"), std::string::npos);
  EXPECT_EQ(c.device_state(), protocol::DeviceState::Lost);
  d.world->allow(1);
  const CaptureResult back = test::next_non_timeout(c);
  ASSERT_EQ(back.status, CaptureStatus::Ok) << back.message;
  EXPECT_TRUE(intact(*back.frame));
  EXPECT_EQ(back.frame->metadata.sequence, 1u);
  const auto events = c.take_events();
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].kind, protocol::EventKind::DeviceLost);
  EXPECT_EQ(events[1].kind, protocol::EventKind::Resumed);
  EXPECT_EQ(c.device_state(), protocol::DeviceState::Streaming);
  {
    std::lock_guard lock(d.world->mu);
    EXPECT_EQ(d.world->open_attempts - attempts_before, 4);
  }
  const protocol::Status s = c.status();
  EXPECT_EQ(s.device_lost_count, 1u);
  EXPECT_EQ(s.device_state, protocol::DeviceState::Streaming);
}

TEST(CaptureDaemon, StillArrivesInItsOwnMemfd) {
  Daemon d;
  CaptureClient c(d.path());
  const CaptureResult r = c.capture_still(StreamConfig{PixelFormat::RGB24, 320, 240, 0}, 2s);
  ASSERT_EQ(r.status, CaptureStatus::Ok) << r.message;
  ASSERT_TRUE(r.frame);
  EXPECT_EQ(r.frame->format.width, 320);
  EXPECT_EQ(r.frame->format.height, 240);
  EXPECT_EQ(r.frame->bytes_used, 320u * 240u * 3u);
  EXPECT_EQ(r.frame->metadata.sequence, 1'000'000u);
  EXPECT_TRUE(intact(*r.frame));
  // A still while the viewfinder streams does not disturb the frames.
  c.start_viewfinder();
  d.world->allow(1);
  ASSERT_EQ(test::next_non_timeout(c).status, CaptureStatus::Ok);
  const CaptureResult again = c.capture_still(std::nullopt, 2s);
  ASSERT_EQ(again.status, CaptureStatus::Ok);
  EXPECT_TRUE(intact(*again.frame));
}

TEST(CaptureDaemon, SetControlsRoundTrip) {
  Daemon d;
  CaptureClient c(d.path());
  CameraControls lock_exposure;
  lock_exposure.auto_exposure = false;
  lock_exposure.exposure_us = 5000;
  lock_exposure.colour_gain_red = 1.5;
  const auto not_applied = c.set_controls(lock_exposure);
  EXPECT_EQ(not_applied, std::vector<std::string>{"colour_gain_red"});
  {
    std::lock_guard lock(d.world->mu);
    EXPECT_EQ(d.world->controls.auto_exposure, std::optional<bool>(false));
    EXPECT_EQ(d.world->controls.exposure_us, std::optional<double>(5000));
  }
  c.start_viewfinder();
  d.world->allow(1);
  const CaptureResult r = test::next_non_timeout(c);
  ASSERT_EQ(r.status, CaptureStatus::Ok);
  EXPECT_EQ(r.frame->metadata.exposure_us, std::optional<double>(5000));  // metadata crosses the wire
  EXPECT_FALSE(r.frame->metadata.analogue_gain);
}

TEST(CaptureDaemon, SelectCameraAndInfo) {
  Daemon d([](CaptureServerOptions& o) {
    o.list_cameras = [] {
      CameraInfo a, b;
      a.id = "test:a";
      b.id = "test:b";
      return std::vector<CameraInfo>{a, b};
    };
  });
  CaptureClient c(d.path());
  const auto cameras = c.list_cameras();
  ASSERT_EQ(cameras.size(), 2u);
  EXPECT_EQ(cameras[1].id, "test:b");
  ASSERT_TRUE(test::eventually([&] { return c.status().device_state == protocol::DeviceState::Idle; }));
  EXPECT_EQ(c.info().id, "test:a");
  c.select_camera("test:b");
  EXPECT_EQ(c.status().camera_id, "test:b");
  const CameraInfo info = c.info();
  EXPECT_EQ(info.id, "test:b");
  EXPECT_EQ(info.backend, "test");
  ASSERT_EQ(info.formats.size(), 2u);
  EXPECT_EQ(info.formats[0].sizes[1].width, 320);
  EXPECT_THROW(c.select_camera("bad:nothing"), CaptureClientError);
  EXPECT_EQ(c.status().camera_id, "test:b");  // the failed switch kept the camera
  c.start_viewfinder();
  d.world->allow(1);
  const CaptureResult r = test::next_non_timeout(c);
  ASSERT_EQ(r.status, CaptureStatus::Ok);
  EXPECT_TRUE(intact(*r.frame));
}

TEST(CaptureDaemon, ConfigureChangesTheFramesAndGrowsTheRing) {
  Daemon d;
  CaptureClient c(d.path());
  ASSERT_TRUE(test::eventually([&] { return c.status().device_state == protocol::DeviceState::Idle; }));
  StreamConfig yuyv{PixelFormat::YUYV, 200, 100, 30};
  EXPECT_EQ(c.configure(yuyv), ConfigStatus::Valid);
  StreamConfig big{PixelFormat::RGB24, 5000, 600, 30};
  EXPECT_EQ(c.configure(big), ConfigStatus::Adjusted);
  EXPECT_EQ(big.width, 1024);
  StreamConfig jpeg{PixelFormat::MJPEG, 64, 48, 30};
  EXPECT_EQ(c.configure(jpeg), ConfigStatus::Invalid);
  EXPECT_EQ(c.status().stream.width, 1024);
  c.start_viewfinder();
  d.world->allow(1);
  const CaptureResult r = test::next_non_timeout(c);
  ASSERT_EQ(r.status, CaptureStatus::Ok);
  EXPECT_EQ(r.frame->format.width, 1024);
  EXPECT_EQ(r.frame->bytes_used, 1024u * 600u * 3u);  // larger than the first ring's slots
  EXPECT_TRUE(intact(*r.frame));
}

TEST(CaptureDaemon, SocketIsGroupReadWriteOnly) {
  Daemon d;
  struct stat st {};
  ASSERT_EQ(::stat(d.path().c_str(), &st), 0);
  EXPECT_TRUE(S_ISSOCK(st.st_mode));
  EXPECT_EQ(st.st_mode & 07777, 0660u);
}

TEST(CaptureDaemon, SocketGoesToItsGroupWhenTheGroupExists) {
  {
    Daemon missing([](CaptureServerOptions& o) { o.socket_group = "propcam-no-such-group"; });
    CaptureClient c(missing.path());  // no group: still serving
  }
  const group* g = ::getgrnam("nogroup");
  if (!g) g = ::getgrnam("daemon");
  if (!g || ::geteuid() != 0) GTEST_SKIP() << "needs root and a nogroup/daemon group";
  const gid_t gid = g->gr_gid;
  const std::string name = g->gr_name;
  Daemon d([&](CaptureServerOptions& o) { o.socket_group = name; });
  struct stat st {};
  ASSERT_EQ(::stat(d.path().c_str(), &st), 0);
  EXPECT_EQ(st.st_gid, gid);
  EXPECT_EQ(st.st_mode & 07777, 0660u);
}

TEST(CaptureDaemon, StaleSocketIsReplaced) {
  const std::string path = test::temp_socket("capture.sock");
  {
    // A socket file left by a server that died: bound, never unlinked, nobody listening.
    const int fd = ::socket(AF_UNIX, SOCK_SEQPACKET, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::strncpy(addr.sun_path, path.c_str(), sizeof addr.sun_path - 1);
    ASSERT_EQ(::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr), 0);
    ::close(fd);
  }
  ASSERT_TRUE(std::filesystem::exists(path));
  auto world = std::make_shared<TestWorld>();
  CaptureServer server(test::test_factory(world), test::test_options(path));
  ASSERT_NO_THROW(server.start());
  CaptureClient c(path);
  EXPECT_EQ(c.status().camera_id, "test:a");
  server.stop();
  EXPECT_FALSE(std::filesystem::exists(path));  // removed on a clean stop
}

TEST(CaptureDaemon, SecondServerRefusesALiveSocket) {
  Daemon d;
  auto world = std::make_shared<TestWorld>();
  CaptureServer second(test::test_factory(world), test::test_options(d.path()));
  EXPECT_THROW(second.start(), std::runtime_error);
  second.stop();
  // The first still serves, and its socket file is still there.
  CaptureClient c(d.path());
  EXPECT_EQ(c.status().camera_id, "test:a");
}

TEST(CaptureDaemon, DaemonFrameSourceBehavesLikeACamera) {
  Daemon d;
  DaemonFrameSource source(d.path());
  FrameSource& camera = source;
  // The daemon opens its camera on its own thread: wait for it before asking.
  ASSERT_TRUE(test::eventually([&] { return source.client().status().device_state == protocol::DeviceState::Idle; }));
  EXPECT_EQ(camera.info().id, "test:a");
  StreamConfig c{PixelFormat::YUYV, 64, 48, 30};
  EXPECT_EQ(camera.configure(c), ConfigStatus::Valid);
  EXPECT_EQ(camera.configuration().pixel_format, PixelFormat::YUYV);
  EXPECT_FALSE(camera.running());
  EXPECT_THROW(camera.next_frame(10ms), std::logic_error);
  camera.start();
  EXPECT_TRUE(camera.running());
  for (std::uint64_t i = 0; i < 3; ++i) {
    round_trip(source.client());
    d.world->allow(1);
    CaptureResult r;
    for (int k = 0; k < 100 && r.status != CaptureStatus::Ok; ++k) r = camera.next_frame(200ms);
    ASSERT_EQ(r.status, CaptureStatus::Ok);
    EXPECT_EQ(r.frame->format.pixel_format, PixelFormat::YUYV);
    EXPECT_EQ(r.frame->metadata.sequence, i);
    EXPECT_TRUE(intact(*r.frame));
  }
  CameraControls gain;
  gain.analogue_gain = 2;
  EXPECT_TRUE(camera.set_controls(gain).empty());
  EXPECT_EQ(camera.capture_still(std::nullopt, 1s).status, CaptureStatus::Ok);
  camera.stop();
  EXPECT_FALSE(camera.running());
}

TEST(CaptureDaemon, BenchMeasuresFramesAndLatency) {
  DaemonBenchOptions o;
  o.socket_path = test::temp_socket("bench.sock");
  o.stream = StreamConfig{PixelFormat::YUYV, 64, 48, 200};
  o.frames = 40;
  const DaemonBenchResult r = measure_daemon_throughput(synthetic_source_factory(), o);
  EXPECT_EQ(r.stopped_because, "frames");
  EXPECT_EQ(r.frames_received, 40);
  EXPECT_GT(r.fps, 0);
  EXPECT_GE(r.frames_captured, 40u);
  EXPECT_GE(r.total.mean_ms, 0);
  EXPECT_GE(r.total.p95_ms, 0);
  EXPECT_LE(r.total.mean_ms, r.total.max_ms);
  EXPECT_GE(r.source.mean_ms, 0);
  EXPECT_GE(r.daemon.mean_ms, 0);
  EXPECT_FALSE(std::filesystem::exists(o.socket_path));
  EXPECT_THROW(measure_daemon_throughput(synthetic_source_factory(), DaemonBenchOptions{"", "x", {}, 0, {}, {}}),
               std::invalid_argument);
}

TEST(CaptureDaemon, FloodBenchMeasuresAStillsLatency) {
  FloodBenchOptions o;
  o.socket_path = test::temp_socket("flood.sock");
  o.stream = StreamConfig{PixelFormat::YUYV, 64, 48, 0};
  o.still_time = 1ms;
  o.flood_depth = 4;
  o.stills = 3;
  const FloodBenchResult r = measure_still_latency_under_flood(synthetic_source_factory(), o);
  EXPECT_EQ(r.stills, 3);
  EXPECT_GT(r.latency.mean_ms, 0);
  EXPECT_LE(r.latency.mean_ms, r.latency.max_ms);
  EXPECT_FALSE(std::filesystem::exists(o.socket_path));
  o.stills = 0;
  EXPECT_THROW(measure_still_latency_under_flood(synthetic_source_factory(), o), std::invalid_argument);
}

// Not run by default: a well-behaved client's still latency while another
// floods, on the virtual board's recording, each still taking 100 ms
// (capture_tests --gtest_also_run_disabled_tests --gtest_filter='*MeasureStillLatency*').
TEST(CaptureDaemon, DISABLED_MeasureStillLatencyUnderAFlood) {
  const std::string recording = PROPCAM_SOURCE_DIR "/board/virtual/recordings/living_room";
  FloodBenchOptions o;
  o.camera_id = "replay:" + recording;
  o.stream = StreamConfig{PixelFormat::YUYV, 640, 480, 0};
  o.still_time = 100ms;
  o.flood_depth = 64;
  o.stills = 10;
  const FloodBenchResult r = measure_still_latency_under_flood(
      [recording](const std::string&) { return std::make_unique<ReplaySource>(recording); }, o);
  std::printf("flood of %d requests, stills of %lld ms: %d stills in %.1f s, latency mean %.0f p95 %.0f max %.0f ms; "
              "flood: %llu stills, %llu refused\n",
              o.flood_depth, static_cast<long long>(o.still_time.count()), r.stills, r.seconds, r.latency.mean_ms,
              r.latency.p95_ms, r.latency.max_ms, static_cast<unsigned long long>(r.flood_stills),
              static_cast<unsigned long long>(r.flood_refused));
}

// Not run by default: prints the daemon's figures
// (capture_tests --gtest_also_run_disabled_tests --gtest_filter='*MeasureDaemon*').
TEST(CaptureDaemon, DISABLED_MeasureDaemonThroughput) {
  struct Case {
    const char* name;
    StreamConfig stream;
    int frames;
  };
  const Case cases[] = {{"640x480 YUYV @30", {PixelFormat::YUYV, 640, 480, 30}, 150},
                        {"640x480 YUYV unpaced", {PixelFormat::YUYV, 640, 480, 0}, 2000},
                        {"1280x720 NV12 unpaced", {PixelFormat::NV12, 1280, 720, 0}, 1000},
                        {"1920x1080 YUYV unpaced", {PixelFormat::YUYV, 1920, 1080, 0}, 500}};
  for (const Case& c : cases) {
    DaemonBenchOptions o;
    o.stream = c.stream;
    o.frames = c.frames;
    const DaemonBenchResult r = measure_daemon_throughput(synthetic_source_factory(), o);
    std::printf("%-24s %5d frames %7.1f fps  total mean %.3f p95 %.3f ms  daemon mean %.3f p95 %.3f ms  "
                "source mean %.3f ms  captured %llu dropped %llu gaps %llu\n",
                c.name, r.frames_received, r.fps, r.total.mean_ms, r.total.p95_ms, r.daemon.mean_ms, r.daemon.p95_ms,
                r.source.mean_ms, static_cast<unsigned long long>(r.frames_captured),
                static_cast<unsigned long long>(r.frames_dropped), static_cast<unsigned long long>(r.sequence_gaps));
  }
}

}  // namespace
}  // namespace propcam::capture
