// Hard cases for the capture formats, recordings and replay: every way a
// camera, a disk or a hand-edited file can hand us broken input. Each must
// end in a clear std::runtime_error (or a correct result), never a crash,
// a hang or an exit() from inside libjpeg.
#include <gtest/gtest.h>
#include <unistd.h>

#include <climits>
#include <filesystem>
#include <fstream>
#include <OpenImageIO/imageio.h>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "propcam/capture/image_file.h"
#include "propcam/capture/pixel_format.h"
#include "propcam/capture/recording.h"
#include "propcam/capture/replay_source.h"

namespace propcam::capture {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("propcam_capture_hard_" + std::to_string(::getpid())) / name;
  fs::remove_all(dir);
  fs::create_directories(dir.parent_path());
  return dir;
}

FrameFormat format_of(PixelFormat pf, int w, int h, int stride = 0) {
  FrameFormat f;
  f.pixel_format = pf;
  f.width = w;
  f.height = h;
  f.stride = stride;
  return f;
}

cv::Mat noise(int w, int h, int seed) {
  cv::Mat img(h, w, CV_8UC3);
  cv::RNG rng(seed);
  rng.fill(img, cv::RNG::UNIFORM, 0, 256);
  return img;
}

std::vector<std::uint8_t> bytes_of(const Frame& f) { return {f.data().begin(), f.data().end()}; }

// Converts, and says how it went: "ok" or the error message. Any exception
// other than std::runtime_error fails the test.
std::string outcome(const Frame& f) {
  try {
    const cv::Mat rgb = frame_to_rgb8(f);
    EXPECT_EQ(rgb.size(), cv::Size(f.format.width, f.format.height));
    return "ok";
  } catch (const std::runtime_error& e) {
    EXPECT_GT(std::string(e.what()).size(), 10u);
    return e.what();
  }
}

// ---------------------------------------------------------------------------
// MJPEG

TEST(CaptureHardCases, EveryTruncatedJpegIsRefused) {
  const Frame good = rgb8_to_frame(noise(48, 32, 1), format_of(PixelFormat::MJPEG, 48, 32), 80);
  const auto bytes = bytes_of(good);
  ASSERT_EQ(outcome(good), "ok");
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    const std::string o = outcome(frame_from_bytes(good.format, {bytes.begin(), bytes.begin() + n}));
    EXPECT_NE(o, "ok") << "a JPEG cut to " << n << " of " << bytes.size() << " bytes decoded";
  }
}

TEST(CaptureHardCases, CorruptJpegsNeverCrash) {
  const Frame good = rgb8_to_frame(noise(64, 48, 2), format_of(PixelFormat::MJPEG, 64, 48), 90);
  const auto bytes = bytes_of(good);
  cv::RNG rng(3);
  int refused = 0;
  for (int trial = 0; trial < 400; ++trial) {
    auto broken = bytes;
    const int flips = 1 + trial % 8;
    for (int i = 0; i < flips; ++i) broken[rng.uniform(0, static_cast<int>(broken.size()))] ^= 1 << rng.uniform(0, 8);
    refused += outcome(frame_from_bytes(good.format, broken)) != "ok";
  }
  // Flipped bits in entropy-coded noise often still decode (to a wrong
  // picture of the right size); those in markers and tables must be caught.
  EXPECT_GT(refused, 20);
  // Pure garbage, and garbage behind a valid start-of-image marker.
  for (int trial = 0; trial < 50; ++trial) {
    std::vector<std::uint8_t> garbage(static_cast<std::size_t>(rng.uniform(1, 4000)));
    for (auto& b : garbage) b = static_cast<std::uint8_t>(rng.uniform(0, 256));
    if (trial % 2 && garbage.size() > 2) garbage[0] = 0xFF, garbage[1] = 0xD8;
    EXPECT_NE(outcome(frame_from_bytes(good.format, garbage)), "ok");
  }
}

TEST(CaptureHardCases, IncompressibleJpegsGrowTheirBuffer) {
  // Noise at quality 100 takes far more than the half byte per pixel the
  // encoder starts with. Grey noise, so 4:2:0 chroma loses nothing.
  cv::Mat grey(384, 512, CV_8UC1), img;
  cv::RNG(8).fill(grey, cv::RNG::UNIFORM, 0, 256);
  cv::cvtColor(grey, img, cv::COLOR_GRAY2RGB);
  const Frame f = rgb8_to_frame(img, format_of(PixelFormat::MJPEG, 512, 384), 100);
  EXPECT_GT(f.bytes_used, 2 * (512u * 384 / 2 + 16384)) << "the buffer did not need to grow twice";
  EXPECT_LE(f.bytes_used, frame_bytes(f.format));
  EXPECT_GT(cv::PSNR(frame_to_rgb8(f), img), 40);
}

TEST(CaptureHardCases, JpegSizeMustMatchTheFormat) {
  const auto bytes = bytes_of(rgb8_to_frame(noise(64, 48, 4), format_of(PixelFormat::MJPEG, 64, 48)));
  for (auto [w, h] : {std::pair{32, 48}, std::pair{64, 24}, std::pair{128, 96}, std::pair{48, 64}}) {
    const std::string o = outcome(frame_from_bytes(format_of(PixelFormat::MJPEG, w, h), bytes));
    EXPECT_NE(o.find("the JPEG is 64x48"), std::string::npos) << o;
  }
}

TEST(CaptureHardCases, JpegVariantsCamerasSend) {
  cv::Mat rgb = noise(40, 30, 5), bgr;
  cv::GaussianBlur(rgb, rgb, cv::Size(0, 0), 2);  // smooth enough for 4:2:0 chroma
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  const auto decode = [](const std::vector<std::uint8_t>& jpeg, int w, int h) {
    return frame_to_rgb8(frame_from_bytes(format_of(PixelFormat::MJPEG, w, h), jpeg));
  };
  // Greyscale JPEG: expanded to three equal channels.
  std::vector<std::uint8_t> jpeg;
  cv::Mat grey;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  ASSERT_TRUE(cv::imencode(".jpg", grey, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95}));
  const cv::Mat g = decode(jpeg, 40, 30);
  for (int y = 0; y < 30; ++y)
    for (int x = 0; x < 40; ++x) {
      const cv::Vec3b p = g.at<cv::Vec3b>(y, x);
      ASSERT_TRUE(p[0] == p[1] && p[1] == p[2]) << x << "," << y;
    }
  // Progressive and 4:4:4 JPEGs decode to the picture.
  ASSERT_TRUE(cv::imencode(".jpg", bgr, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95, cv::IMWRITE_JPEG_PROGRESSIVE, 1}));
  EXPECT_GT(cv::PSNR(decode(jpeg, 40, 30), rgb), 25);
  {  // OpenCV 4.6 cannot choose the sampling; OpenImageIO can.
    const fs::path path = fresh_dir("jpeg444") += ".jpg";
    OIIO::ImageSpec spec(40, 30, 3, OIIO::TypeDesc::UINT8);
    spec.attribute("jpeg:subsampling", "4:4:4");
    spec.attribute("CompressionQuality", 95);
    auto out = OIIO::ImageOutput::create(path.string());
    ASSERT_TRUE(out && out->open(path.string(), spec) && out->write_image(OIIO::TypeDesc::UINT8, rgb.data) &&
                out->close());
    std::ifstream in(path, std::ios::binary);
    const std::vector<std::uint8_t> j444((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_GT(cv::PSNR(decode(j444, 40, 30), rgb), 30);
  }
  // UVC cameras leave out the Huffman tables (DHT) and rely on the standard
  // ones; our encoder uses exactly those, so strip them and decode the same.
  const auto full = bytes_of(rgb8_to_frame(rgb, format_of(PixelFormat::MJPEG, 40, 30), 90));
  std::vector<std::uint8_t> stripped(full.begin(), full.begin() + 2);
  std::size_t i = 2;
  while (i + 4 <= full.size() && full[i] == 0xFF && full[i + 1] != 0xDA) {
    const std::size_t length = 2 + (full[i + 2] << 8 | full[i + 3]);
    if (full[i + 1] != 0xC4) stripped.insert(stripped.end(), full.begin() + i, full.begin() + i + length);
    i += length;
  }
  stripped.insert(stripped.end(), full.begin() + i, full.end());
  ASSERT_LT(stripped.size(), full.size());
  cv::Mat a = decode(full, 40, 30), b = decode(stripped, 40, 30), d;
  cv::absdiff(a, b, d);
  EXPECT_EQ(cv::countNonZero(d.reshape(1)), 0);
  // Stray bytes between markers (some webcams) are tolerated.
  std::vector<std::uint8_t> stray(full.begin(), full.begin() + 2);
  stray.insert(stray.end(), {0x00, 0x00, 0x00});
  stray.insert(stray.end(), full.begin() + 2, full.end());
  EXPECT_EQ(outcome(frame_from_bytes(format_of(PixelFormat::MJPEG, 40, 30), stray)), "ok");
}

// ---------------------------------------------------------------------------
// Raw formats

TEST(CaptureHardCases, ImplausibleFormatsAreRefusedBeforeAnyAllocation) {
  const std::vector<std::uint8_t> small(64, 0);
  for (const FrameFormat& f :
       {format_of(PixelFormat::YUYV, 16384, 16384), format_of(PixelFormat::RGB24, 16385, 1),
        format_of(PixelFormat::GREY, INT_MAX, INT_MAX), format_of(PixelFormat::NV12, INT_MIN, 2),
        format_of(PixelFormat::GREY, 8, 8, -8), format_of(PixelFormat::GREY, 8, 8, INT_MAX),
        format_of(PixelFormat::RGB24, 8, 8, 23), format_of(PixelFormat::MJPEG, 0, 0),
        format_of(static_cast<PixelFormat>(99), 8, 8)}) {
    EXPECT_NE(outcome(frame_from_bytes(f, small)), "ok");
  }
  EXPECT_THROW(to_string(static_cast<PixelFormat>(99)), std::runtime_error);
  EXPECT_THROW(minimum_stride(PixelFormat::RGB24, -1), std::runtime_error);
  EXPECT_THROW(minimum_stride(PixelFormat::RGB24, INT_MAX), std::runtime_error);
}

TEST(CaptureHardCases, TinyAndLargestFramesConvert) {
  for (const FrameFormat& f : {format_of(PixelFormat::RGB24, 1, 1), format_of(PixelFormat::GREY, 1, 1),
                               format_of(PixelFormat::YUYV, 2, 1), format_of(PixelFormat::UYVY, 2, 1),
                               format_of(PixelFormat::NV12, 2, 2), format_of(PixelFormat::MJPEG, 1, 1),
                               format_of(PixelFormat::BGR24, 1, 16384), format_of(PixelFormat::GREY, 16384, 1)}) {
    const cv::Mat img = noise(f.width, f.height, 6);
    const Frame frame = rgb8_to_frame(img, f);
    EXPECT_EQ(outcome(frame), "ok") << to_string(f.pixel_format);
  }
}

TEST(CaptureHardCases, EveryShortBufferIsRefused) {
  for (PixelFormat pf : {PixelFormat::RGB24, PixelFormat::BGR24, PixelFormat::YUYV, PixelFormat::UYVY,
                         PixelFormat::NV12, PixelFormat::GREY}) {
    const FrameFormat f = format_of(pf, 6, 4, minimum_stride(pf, 6) + 2);
    const auto bytes = bytes_of(rgb8_to_frame(noise(6, 4, 7), f));
    EXPECT_EQ(outcome(frame_from_bytes(f, bytes)), "ok");
    for (std::size_t n = 0; n < bytes.size(); ++n) {
      const std::string o = outcome(frame_from_bytes(f, {bytes.begin(), bytes.begin() + n}));
      EXPECT_NE(o.find("needs " + std::to_string(bytes.size()) + " bytes, has " + std::to_string(n)), std::string::npos)
          << o;
    }
  }
}

TEST(CaptureHardCases, BytesUsedBeyondTheBufferIsRefused) {
  Frame f = frame_from_bytes(format_of(PixelFormat::MJPEG, 8, 8), std::vector<std::uint8_t>(100, 0));
  f.bytes_used = 1'000'000;
  EXPECT_NE(outcome(f).find("exceeds its buffer"), std::string::npos);
}

// ---------------------------------------------------------------------------
// Recordings and replay

fs::path small_recording(const std::string& name, int frames, std::int64_t spacing_ns) {
  const fs::path dir = fresh_dir(name);
  Recorder recorder(dir, "v4l2:/dev/video9");
  for (int i = 0; i < frames; ++i) {
    Frame f = rgb8_to_frame(noise(4, 2, i), format_of(PixelFormat::GREY, 4, 2));
    f.metadata.timestamp_ns = i * spacing_ns;
    f.metadata.sequence = static_cast<std::uint64_t>(i);
    recorder.append(f);
  }
  recorder.finish();
  return dir;
}

std::string load_error(const fs::path& dir) {
  try {
    load_recording(dir);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(CaptureHardCases, RecordingsClaimingTooMuchAreRefusedUnread) {
  // Two 256 MB GREY frames as sparse files: over the 512 MB bound, refused
  // from their sizes alone.
  const fs::path dir = fresh_dir("too_big");
  fs::create_directories(dir);
  const std::size_t frame = 16384u * 16384u;
  nlohmann::json frames = nlohmann::json::array();
  for (int i = 0; i < 3; ++i) {
    const std::string name = "frame_00000" + std::to_string(i) + ".raw";
    { std::ofstream(dir / name).put('\0'); }
    fs::resize_file(dir / name, frame);
    frames.push_back({{"file", name}, {"bytes_used", frame}, {"metadata", {{"timestamp_ns", i}, {"sequence", i}}}});
  }
  const nlohmann::json j = {{"version", 1},
                            {"camera", {{"id", "x"}, {"description", ""}}},
                            {"format",
                             {{"pixel_format", "GREY"},
                              {"width", 16384},
                              {"height", 16384},
                              {"stride", 16384},
                              {"encoding", "bt601"},
                              {"range", "full"}}},
                            {"frames", frames}};
  std::ofstream(dir / "recording.json") << j.dump();
  const std::string e = load_error(dir);
  EXPECT_NE(e.find("more than 512 MB"), std::string::npos) << e;
  EXPECT_THROW(ReplaySource{dir}, std::runtime_error);
  fs::remove_all(dir);
}

TEST(CaptureHardCases, HostileManifests) {
  const fs::path dir = small_recording("hostile", 2, 1000);
  const auto with = [&](const std::string& text) {
    std::ofstream(dir / "recording.json", std::ios::trunc) << text;
    return load_error(dir);
  };
  EXPECT_NE(with("").find("not valid JSON"), std::string::npos);
  EXPECT_NE(with("null").find("not a JSON object"), std::string::npos);
  EXPECT_NE(with(std::string(100000, '[')).find("not valid JSON"), std::string::npos);  // deep nesting
  EXPECT_NE(with("{\"version\": \"1\"}").find("version: is not an integer"), std::string::npos);
  EXPECT_NE(with("{\"version\": 0}").find("version: 0 is outside"), std::string::npos);
  EXPECT_NE(with("{\"version\": 1, \"camera\": 5}").find("camera: is not an object"), std::string::npos);
  // A name with a NUL in it could cut a path short.
  nlohmann::json j = {{"version", 1},
                      {"camera", {{"id", "x"}, {"description", ""}}},
                      {"format",
                       {{"pixel_format", "GREY"},
                        {"width", 4},
                        {"height", 2},
                        {"stride", 4},
                        {"encoding", "bt601"},
                        {"range", "full"}}},
                      {"frames",
                       {{{"file", std::string("frame_000000.raw\0/../../etc", 27)},
                         {"bytes_used", 8},
                         {"metadata", {{"timestamp_ns", 0}, {"sequence", 0}}}}}}};
  const std::string nul = with(j.dump());
  EXPECT_NE(nul.find("'frame_000000.raw\\x00/../../etc' is not a plain file name"), std::string::npos) << nul;
  j["frames"][0]["file"] = "frame_000000.raw";
  j["frames"][0]["metadata"]["timestamp_ns"] = -1;
  EXPECT_NE(with(j.dump()).find("timestamp_ns: -1 is outside"), std::string::npos);
  j["frames"][0]["metadata"]["timestamp_ns"] = 0;
  j["frames"][0]["bytes_used"] = 1e30;
  EXPECT_NE(with(j.dump()).find("bytes_used: is not an integer"), std::string::npos);
  j["frames"][0]["bytes_used"] = 8;
  EXPECT_EQ(with(j.dump()), "");  // and the repaired manifest loads
  // Over-long manifests are refused before parsing.
  std::ofstream(dir / "recording.json", std::ios::trunc) << std::string(65u << 20, ' ');
  EXPECT_NE(load_error(dir).find("larger than 64 MB"), std::string::npos);
  fs::remove_all(dir);
}

TEST(CaptureHardCases, ReplayOfImplausibleClocks) {
  // A recording over 30 days long cannot be paced.
  const fs::path long_dir = small_recording("years", 2, std::int64_t{40} * 24 * 3600 * 1'000'000'000);
  EXPECT_EQ(load_error(long_dir), "");
  try {
    ReplaySource source(long_dir);
    FAIL() << "replayed a 40-day recording";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("more than 30 days"), std::string::npos) << e.what();
  }
  // All frames at the same instant: realtime replay hands out the newest due
  // frame, in order, without hanging or repeating.
  ReplaySource same(small_recording("same_instant", 4, 0));
  EXPECT_EQ(same.recorded_fps(), 0);
  same.start();
  std::uint64_t last = 0;
  std::int64_t last_ts = 0;
  for (int i = 0; i < 6; ++i) {
    const CaptureResult r = same.next_frame(milliseconds(1000));
    ASSERT_EQ(r.status, CaptureStatus::Ok) << r.message;
    if (i) {
      EXPECT_GT(r.frame->metadata.sequence, last);
      EXPECT_GE(r.frame->metadata.timestamp_ns, last_ts);
    }
    last = r.frame->metadata.sequence;
    last_ts = r.frame->metadata.timestamp_ns;
  }
}

TEST(CaptureHardCases, ReplayedBytesStayBoundAndShared) {
  // Frames share the loaded bytes instead of copying them per delivery.
  ReplayOptions o;
  o.pacing = ReplayPacing::AsFastAsPossible;
  ReplaySource source(small_recording("shared", 2, 1000), o);
  source.start();
  const Frame a = *source.next_frame(milliseconds(0)).frame;
  source.next_frame(milliseconds(0));
  const Frame c = *source.next_frame(milliseconds(0)).frame;
  EXPECT_EQ(a.buffer.get(), c.buffer.get());
  EXPECT_EQ(c.metadata.sequence, 2u);
}

// Found by tests/fuzz/fuzz_image: a 69-byte PNG whose header claims
// 60000x60000 RGBA16. The float pixels (57 GB) were allocated before a row
// was read; now the size is refused first, naming the file.
TEST(CaptureHardCases, AnImageHeaderClaimingAHugeSizeIsRefusedUnread) {
  const unsigned char png[] = {
    0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d,
    0x49, 0x48, 0x44, 0x52, 0x00, 0x00, 0xea, 0x60, 0x00, 0x00, 0xea, 0x60,
    0x10, 0x06, 0x00, 0x00, 0x00, 0xd0, 0x42, 0xa9, 0x01, 0x00, 0x00, 0x00,
    0x0c, 0x49, 0x44, 0x41, 0x54, 0x78, 0x9c, 0x63, 0x60, 0xa0, 0x0c, 0x00,
    0x00, 0x00, 0x40, 0x00, 0x01, 0xb7, 0x34, 0x7c, 0xef, 0x00, 0x00, 0x00,
    0x00, 0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82,
  };
  const fs::path dir = fresh_dir("huge_header");
  fs::create_directories(dir);
  const fs::path path = dir / "huge.png";
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(png), sizeof png);
  for (auto load : {&read_image_float, &load_photo_linear}) {
    try {
      load(path.string());
      ADD_FAILURE() << "a 60000x60000 header was read";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("too large"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("huge.png"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace propcam::capture
