#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "propcam/capture/pixel_format.h"
#include "propcam/capture/recording.h"

namespace propcam::capture {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// A fresh folder per test, removed first so reruns start clean.
fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("propcam_recording_test_" + std::to_string(::getpid())) / name;
  fs::remove_all(dir);
  fs::create_directories(dir.parent_path());
  return dir;
}

Frame test_frame(PixelFormat pf, int w, int h, int seed) {
  cv::Mat img(h, w, CV_8UC3);
  cv::RNG rng(seed);
  rng.fill(img, cv::RNG::UNIFORM, 0, 256);
  FrameFormat f;
  f.pixel_format = pf;
  f.width = w;
  f.height = h;
  f.encoding = YcbcrEncoding::Bt709;
  f.range = QuantisationRange::Full;
  return rgb8_to_frame(img, f);
}

fs::path write_recording(const fs::path& dir, int frames, PixelFormat pf = PixelFormat::YUYV) {
  Recorder recorder(dir, "v4l2:/dev/video0", "UVC Camera (046d:0825)");
  for (int i = 0; i < frames; ++i) {
    Frame f = test_frame(pf, 8, 6, i);
    f.metadata.timestamp_ns = 1'000'000'000 + i * 33'333'333LL;
    f.metadata.sequence = 100 + i;
    if (i == 1) {
      f.metadata.exposure_us = 8000.5;
      f.metadata.analogue_gain = 2.0;
      f.metadata.colour_gain_red = 1.8;
      f.metadata.colour_gain_blue = 1.4;
      f.metadata.colour_temperature_k = 5200;
    }
    recorder.append(f);
  }
  recorder.finish();
  return dir;
}

json read_json(const fs::path& dir) {
  std::ifstream in(dir / "recording.json");
  return json::parse(in);
}

void write_json(const fs::path& dir, const json& j) {
  std::ofstream(dir / "recording.json") << j.dump(2);
}

// The message load_recording throws ("" when it loads).
std::string load_error(const fs::path& dir) {
  try {
    load_recording(dir);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

// Breaks one thing in a good recording's JSON and returns the load error.
template <typename Edit>
std::string error_after(const std::string& name, Edit edit) {
  const fs::path dir = write_recording(fresh_dir(name), 3);
  json j = read_json(dir);
  edit(j);
  write_json(dir, j);
  return load_error(dir);
}

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

// ---------------------------------------------------------------------------

TEST(Recording, WriteThenLoadIsByteIdentical) {
  const fs::path dir = fresh_dir("round_trip");
  std::vector<Frame> written;
  {
    Recorder recorder(dir, "v4l2:/dev/video0", "UVC Camera");
    for (int i = 0; i < 4; ++i) {
      Frame f = test_frame(PixelFormat::NV12, 16, 8, i);
      f.metadata.timestamp_ns = 5'000'000 + i * 40'000'000LL;
      f.metadata.sequence = static_cast<std::uint64_t>(7 + 2 * i);  // a dropped frame between each
      f.metadata.exposure_us = 1000.0 * (i + 1);
      if (i % 2) f.metadata.colour_temperature_k = 6500;
      recorder.append(f);
      written.push_back(f);
    }
    EXPECT_EQ(recorder.frame_count(), 4u);
    const Recording& r = recorder.finish();
    EXPECT_TRUE(recorder.finished());
    EXPECT_EQ(r.frames[3].file, "frame_000003.raw");
  }
  EXPECT_TRUE(fs::is_regular_file(dir / "recording.json"));
  EXPECT_TRUE(fs::is_regular_file(dir / "frame_000000.raw"));
  EXPECT_EQ(fs::file_size(dir / "frame_000000.raw"), written[0].bytes_used);
  // No temporaries left behind.
  for (const auto& entry : fs::directory_iterator(dir)) EXPECT_NE(entry.path().filename().string()[0], '.');

  const Recording r = load_recording(dir);
  EXPECT_EQ(r.version, kRecordingVersion);
  EXPECT_EQ(r.camera_id, "v4l2:/dev/video0");
  EXPECT_EQ(r.camera_description, "UVC Camera");
  EXPECT_EQ(r.format.pixel_format, PixelFormat::NV12);
  EXPECT_EQ(r.format.width, 16);
  EXPECT_EQ(r.format.height, 8);
  EXPECT_EQ(r.format.stride, 16);
  EXPECT_EQ(r.format.encoding, YcbcrEncoding::Bt709);
  EXPECT_EQ(r.format.range, QuantisationRange::Full);
  ASSERT_EQ(r.frames.size(), 4u);
  EXPECT_EQ(r.total_bytes(), 4u * 16 * 12);

  const std::vector<Frame> loaded = load_recording_frames(r);
  ASSERT_EQ(loaded.size(), 4u);
  for (std::size_t i = 0; i < 4; ++i) {
    const auto a = written[i].data(), b = loaded[i].data();
    EXPECT_TRUE(std::equal(a.begin(), a.end(), b.begin(), b.end())) << "frame " << i;
    EXPECT_EQ(loaded[i].metadata.timestamp_ns, written[i].metadata.timestamp_ns);
    EXPECT_EQ(loaded[i].metadata.sequence, written[i].metadata.sequence);
    EXPECT_EQ(loaded[i].metadata.exposure_us, written[i].metadata.exposure_us);
    EXPECT_EQ(loaded[i].metadata.colour_temperature_k, written[i].metadata.colour_temperature_k);
    EXPECT_FALSE(loaded[i].metadata.analogue_gain);
    EXPECT_EQ(loaded[i].format.pixel_format, PixelFormat::NV12);
  }
  // The JSON is what the README says.
  const json j = read_json(dir);
  EXPECT_EQ(j["format"]["pixel_format"], "NV12");
  EXPECT_EQ(j["format"]["encoding"], "bt709");
  EXPECT_EQ(j["format"]["range"], "full");
  EXPECT_EQ(j["frames"][1]["metadata"]["colour_temperature_k"], 6500.0);
  EXPECT_FALSE(j["frames"][0]["metadata"].contains("colour_temperature_k"));
}

TEST(Recording, MjpegFramesKeepTheirOwnLengths) {
  const fs::path dir = write_recording(fresh_dir("mjpeg"), 3, PixelFormat::MJPEG);
  const Recording r = load_recording(dir);
  EXPECT_EQ(r.format.stride, 0);
  const auto frames = load_recording_frames(r);
  for (int i = 0; i < 3; ++i) {
    const Frame original = test_frame(PixelFormat::MJPEG, 8, 6, i);
    EXPECT_EQ(frames[i].bytes_used, original.bytes_used);
    EXPECT_EQ(frame_to_rgb8(frames[i]).size(), cv::Size(8, 6));
  }
  const auto metadata = r.frames[1].metadata;
  EXPECT_EQ(metadata.exposure_us, 8000.5);
  EXPECT_EQ(metadata.analogue_gain, 2.0);
  EXPECT_EQ(metadata.colour_gain_red, 1.8);
  EXPECT_EQ(metadata.colour_gain_blue, 1.4);
  EXPECT_EQ(metadata.colour_temperature_k, 5200);
}

TEST(Recording, RecorderRefusesMisuse) {
  const fs::path used = write_recording(fresh_dir("used"), 1);
  EXPECT_THROW(Recorder(used, "x"), std::runtime_error);  // not empty
  const fs::path file = fresh_dir("a_file");
  std::ofstream(file) << "x";
  EXPECT_THROW(Recorder(file, "x"), std::runtime_error);

  Recorder empty(fresh_dir("empty"), "x");
  EXPECT_THROW(empty.finish(), std::runtime_error);  // no frames

  Recorder recorder(fresh_dir("mismatch"), "x");
  recorder.append(test_frame(PixelFormat::YUYV, 8, 6, 0));
  EXPECT_THROW(recorder.append(test_frame(PixelFormat::YUYV, 10, 6, 0)), std::runtime_error);
  EXPECT_THROW(recorder.append(test_frame(PixelFormat::UYVY, 8, 6, 0)), std::runtime_error);
  Frame short_frame = test_frame(PixelFormat::YUYV, 8, 6, 0);
  short_frame.bytes_used = 10;
  EXPECT_THROW(recorder.append(short_frame), std::runtime_error);
  Frame no_buffer = test_frame(PixelFormat::YUYV, 8, 6, 0);
  no_buffer.buffer.reset();
  EXPECT_THROW(recorder.append(no_buffer), std::runtime_error);
  EXPECT_EQ(recorder.frame_count(), 1u);
  recorder.finish();
  EXPECT_THROW(recorder.append(test_frame(PixelFormat::YUYV, 8, 6, 0)), std::logic_error);
}

TEST(Recording, UnfinishedRecordingDoesNotLoad) {
  const fs::path dir = fresh_dir("unfinished");
  {
    Recorder recorder(dir, "x");
    recorder.append(test_frame(PixelFormat::GREY, 8, 6, 0));
  }
  EXPECT_TRUE(fs::exists(dir / "frame_000000.raw"));
  const std::string e = load_error(dir);
  EXPECT_TRUE(contains(e, "recording.json: missing")) << e;
}

TEST(Recording, GarbledJsonNamesTheFile) {
  const fs::path dir = write_recording(fresh_dir("garbled"), 2);
  std::ofstream(dir / "recording.json") << "{\"version\": 1, \"frames\": [";
  const std::string e = load_error(dir);
  EXPECT_TRUE(contains(e, (dir / "recording.json").string())) << e;
  EXPECT_TRUE(contains(e, "not valid JSON")) << e;
  std::ofstream(dir / "recording.json") << "[1, 2]";
  EXPECT_TRUE(contains(load_error(dir), "is not a JSON object"));
}

TEST(Recording, MissingAndMistypedFieldsAreNamed) {
  std::string e = error_after("no_format", [](json& j) { j.erase("format"); });
  EXPECT_TRUE(contains(e, "recording.json: missing field 'format'")) << e;
  e = error_after("no_width", [](json& j) { j["format"].erase("width"); });
  EXPECT_TRUE(contains(e, "format: missing field 'width'")) << e;
  e = error_after("no_bytes_used", [](json& j) { j["frames"][2].erase("bytes_used"); });
  EXPECT_TRUE(contains(e, "frames[2]: missing field 'bytes_used'")) << e;
  e = error_after("no_sequence", [](json& j) { j["frames"][1]["metadata"].erase("sequence"); });
  EXPECT_TRUE(contains(e, "frames[1].metadata: missing field 'sequence'")) << e;
  e = error_after("string_width", [](json& j) { j["format"]["width"] = "640"; });
  EXPECT_TRUE(contains(e, "format.width: is not an integer")) << e;
  e = error_after("float_height", [](json& j) { j["format"]["height"] = 6.5; });
  EXPECT_TRUE(contains(e, "format.height: is not an integer")) << e;
  e = error_after("bad_exposure", [](json& j) { j["frames"][0]["metadata"]["exposure_us"] = "long"; });
  EXPECT_TRUE(contains(e, "frames[0].metadata.exposure_us: is not a finite number")) << e;
  e = error_after("no_camera", [](json& j) { j["camera"].erase("id"); });
  EXPECT_TRUE(contains(e, "camera: missing field 'id'")) << e;
  e = error_after("frames_object", [](json& j) { j["frames"] = json::object(); });
  EXPECT_TRUE(contains(e, "frames: is not an array")) << e;
  e = error_after("no_frames", [](json& j) { j["frames"] = json::array(); });
  EXPECT_TRUE(contains(e, "frames: no frames")) << e;
  e = error_after("newer", [](json& j) { j["version"] = 2; });
  EXPECT_TRUE(contains(e, "version: 2 is newer than this build reads")) << e;
}

TEST(Recording, BadFormatsAreRejected) {
  std::string e = error_after("unknown_format", [](json& j) { j["format"]["pixel_format"] = "H264"; });
  EXPECT_TRUE(contains(e, "unknown pixel format 'H264'")) << e;
  e = error_after("negative_width", [](json& j) { j["format"]["width"] = -8; });
  EXPECT_TRUE(contains(e, "format.width: -8 is outside 1..16384")) << e;
  e = error_after("huge_height", [](json& j) { j["format"]["height"] = 1'000'000; });
  EXPECT_TRUE(contains(e, "format.height: 1000000 is outside")) << e;
  e = error_after("enormous_width", [](json& j) { j["format"]["width"] = 18446744073709551615ull; });
  EXPECT_TRUE(contains(e, "format.width: 18446744073709551615 is outside")) << e;
  e = error_after("odd_width", [](json& j) { j["format"]["width"] = 7; });
  EXPECT_TRUE(contains(e, "width must be even")) << e;
  e = error_after("bad_stride", [](json& j) { j["format"]["stride"] = 4; });
  EXPECT_TRUE(contains(e, "stride 4 outside")) << e;
  e = error_after("bad_range", [](json& j) { j["format"]["range"] = "studio"; });
  EXPECT_TRUE(contains(e, "unknown range 'studio'")) << e;
}

TEST(Recording, RawFilesMustMatchAndStayInside) {
  const auto traversal = [](const std::string& name) {
    return error_after("traversal_" + std::to_string(std::hash<std::string>{}(name)),
                       [&](json& j) { j["frames"][0]["file"] = name; });
  };
  for (const std::string name : {"../x", "/etc/passwd", "sub/frame.raw", "..", ".", ".hidden", "", "a\\b"}) {
    const std::string e = traversal(name);
    EXPECT_TRUE(contains(e, "frames[0].file")) << name << ": " << e;
    EXPECT_TRUE(contains(e, "not a plain file name")) << name << ": " << e;
  }
  const fs::path dir = write_recording(fresh_dir("sizes"), 3);
  { std::ofstream(dir / "frame_000001.raw", std::ios::app) << "extra"; }
  std::string e = load_error(dir);
  EXPECT_TRUE(contains(e, "frames[1]: raw file")) << e;
  EXPECT_TRUE(contains(e, "has 101 bytes, bytes_used says 96")) << e;
  fs::remove(dir / "frame_000001.raw");
  e = load_error(dir);
  EXPECT_TRUE(contains(e, "frame_000001.raw is missing")) << e;
  // A symbolic link could lead out of the folder.
  fs::create_symlink(dir / "frame_000000.raw", dir / "frame_000001.raw");
  e = load_error(dir);
  EXPECT_TRUE(contains(e, "is not a regular file")) << e;

  e = error_after("short_bytes_used", [](json& j) { j["frames"][0]["bytes_used"] = 10; });
  EXPECT_TRUE(contains(e, "bytes_used 10 is less than the 96")) << e;
  e = error_after("duplicate", [](json& j) { j["frames"][2]["file"] = "frame_000000.raw"; });
  EXPECT_TRUE(contains(e, "listed twice")) << e;
  e = error_after("backwards", [](json& j) { j["frames"][2]["metadata"]["timestamp_ns"] = 5; });
  EXPECT_TRUE(contains(e, "frames[2].metadata.timestamp_ns: goes backwards")) << e;
}

TEST(Recording, LoadingFramesRechecksTheFiles) {
  const fs::path dir = write_recording(fresh_dir("changed"), 2);
  const Recording r = load_recording(dir);
  fs::resize_file(dir / "frame_000001.raw", 3);
  try {
    load_recording_frames(r);
    FAIL() << "a shrunken raw file was loaded";
  } catch (const std::runtime_error& e) {
    EXPECT_TRUE(contains(e.what(), "frame_000001.raw: size differs")) << e.what();
  }
}

}  // namespace
}  // namespace propcam::capture
