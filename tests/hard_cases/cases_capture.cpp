// capture: frames whose bytes do not match their format, tiny and padded
// frames, corrupt JPEGs, broken image files and recordings, non-finite pixels
// at the sRGB edge.
#include <filesystem>
#include <fstream>
#include <limits>

#include "catalogue.h"
#include "propcam/capture/frame.h"
#include "propcam/capture/image_file.h"
#include "propcam/capture/pixel_format.h"
#include "propcam/capture/recording.h"

namespace propcam::hard_cases {
namespace {

namespace fs = std::filesystem;
using capture::FrameFormat;
using capture::PixelFormat;

std::vector<std::uint8_t> ramp_bytes(std::size_t n) {
  std::vector<std::uint8_t> b(n);
  for (std::size_t i = 0; i < n; ++i) b[i] = static_cast<std::uint8_t>(i * 37 + 11);
  return b;
}

capture::Frame frame(PixelFormat pf, int w, int h, int stride, std::size_t bytes) {
  FrameFormat f;
  f.pixel_format = pf;
  f.width = w;
  f.height = h;
  f.stride = stride;
  return capture::frame_from_bytes(f, ramp_bytes(bytes));
}

cv::Mat small_rgb8(int w, int h) {
  cv::Mat m(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) m.at<cv::Vec3b>(y, x) = cv::Vec3b(x * 20, y * 30, (x + y) * 9);
  return m;
}

// `half`: the first half of `full`'s bytes (a file cut short in a copy).
void write_first_half(const fs::path& full, const fs::path& half) {
  std::ifstream in(full, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  write_text_file(half, bytes.substr(0, bytes.size() / 2));
}

// A valid one-frame RGB24 recording of 4x2 pixels, for corrupting.
void write_recording(const fs::path& dir) {
  capture::Recorder rec(dir, "hard:case");
  FrameFormat f;
  f.pixel_format = PixelFormat::RGB24;
  f.width = 4;
  f.height = 2;
  rec.append(capture::frame_from_bytes(f, ramp_bytes(24)));
  rec.finish();
}

void replace_in_file(const fs::path& file, const std::string& from, const std::string& to) {
  std::ifstream in(file);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto at = text.find(from);
  check(at != std::string::npos, "setup: '" + from + "' not in " + file.string());
  text.replace(at, from.size(), to);
  write_text_file(file, text);
}

}  // namespace

void add_capture_cases(std::vector<HardCase>& cases) {
  const std::string m = "capture";
  cases.push_back({"YuyvStrideBelowMinimum", m, "YUYV 8x4 frame with a 8-byte stride (minimum 16)",
                   "error naming the stride", Expect::Error, {"stride"}, [](Digest&) {
                     capture::frame_to_rgb8(frame(PixelFormat::YUYV, 8, 4, 8, 64));
                   }});
  cases.push_back({"Nv12OddHeight", m, "NV12 4x3 frame (4:2:0 needs an even height)", "error naming the odd height",
                   Expect::Error, {"height"}, [](Digest&) {
                     capture::frame_to_rgb8(frame(PixelFormat::NV12, 4, 3, 4, 18));
                   }});
  cases.push_back({"RgbBufferOneByteShort", m, "RGB24 4x4 frame with 47 of its 48 bytes",
                   "error saying how many bytes it needs", Expect::Error, {"needs 48"}, [](Digest&) {
                     capture::frame_to_rgb8(frame(PixelFormat::RGB24, 4, 4, 0, 47));
                   }});
  cases.push_back({"ImplausibleDimensions", m, "GREY frame format of 100000x100000",
                   "error naming the width, before any allocation", Expect::Error, {"width"}, [](Digest&) {
                     FrameFormat f;
                     f.pixel_format = PixelFormat::GREY;
                     f.width = f.height = 100000;
                     capture::validate_frame_format(f);
                   }});
  cases.push_back({"OneByOneRgbFrame", m, "RGB24 1x1 frame through frame_to_linear", "one finite linear pixel",
                   Expect::Result, {}, [](Digest& d) {
                     const cv::Mat lin = capture::frame_to_linear(frame(PixelFormat::RGB24, 1, 1, 0, 3));
                     check(lin.size() == cv::Size(1, 1) && lin.type() == CV_32FC3, "a 1x1 CV_32FC3 image");
                     d.mat(lin);
                   }});
  cases.push_back({"Nv12PaddedStride", m, "NV12 6x4 frame with a 16-byte stride and garbage in the padding",
                   "the same pixels as the packed frame (padding ignored)", Expect::Result, {}, [](Digest& d) {
                     const capture::Frame packed = frame(PixelFormat::NV12, 6, 4, 6, 36);
                     std::vector<std::uint8_t> padded(16 * 6, 0xEE);
                     const auto src = packed.data();
                     for (int row = 0; row < 6; ++row)
                       std::copy_n(src.begin() + row * 6, 6, padded.begin() + row * 16);
                     FrameFormat f = packed.format;
                     f.stride = 16;
                     const cv::Mat a = capture::frame_to_rgb8(capture::frame_from_bytes(f, padded));
                     const cv::Mat b = capture::frame_to_rgb8(packed);
                     check(cv::norm(a, b, cv::NORM_INF) == 0, "padding changed the pixels");
                     d.mat(a);
                   }});
  cases.push_back({"GarbageMjpeg", m, "MJPEG 16x16 frame whose bytes are not a JPEG", "error naming the JPEG",
                   Expect::Error, {"jpeg"}, [](Digest&) {
                     capture::frame_to_rgb8(frame(PixelFormat::MJPEG, 16, 16, 0, 200));
                   }});
  cases.push_back({"MjpegOfTheWrongSize", m, "a valid 16x16 JPEG in a frame that says 32x32",
                   "error naming both sizes", Expect::Error, {"16x16", "32x32"}, [](Digest&) {
                     FrameFormat f16;
                     f16.pixel_format = PixelFormat::MJPEG;
                     f16.width = f16.height = 16;
                     capture::Frame jpeg = capture::rgb8_to_frame(small_rgb8(16, 16), f16);
                     jpeg.format.width = jpeg.format.height = 32;
                     capture::frame_to_rgb8(jpeg);
                   }});
  cases.push_back({"TruncatedPng", m, "an 8x8 PNG cut to half its bytes, through load_photo_linear",
                   "error naming the file", Expect::Error, {"half.png"}, [](Digest&) {
                     ScratchDir dir("TruncatedPng");
                     const fs::path full = dir / "full.png", half = dir / "half.png";
                     capture::write_image(full.string(), small_rgb8(8, 8));
                     write_first_half(full, half);
                     capture::load_photo_linear(half.string());
                   }});
  cases.push_back({"TruncatedJpeg", m, "a 128x96 JPEG cut to half its bytes, through load_photo_linear",
                   "error naming the file and the cut", Expect::Error, {"half.jpg", "cut short"}, [](Digest&) {
                     ScratchDir dir("TruncatedJpeg");
                     const fs::path full = dir / "full.jpg", half = dir / "half.jpg";
                     capture::write_image(full.string(), small_rgb8(128, 96));
                     capture::load_photo_linear(full.string());  // whole, it reads
                     write_first_half(full, half);
                     capture::load_photo_linear(half.string());
                   }});
  cases.push_back({"FolderGivenAsPhoto", m, "a folder named photo.png, through load_photo_linear",
                   "error saying it is a folder", Expect::Error, {"photo.png", "folder"}, [](Digest&) {
                     ScratchDir dir("FolderGivenAsPhoto");
                     fs::create_directories(dir / "photo.png");
                     capture::load_photo_linear((dir / "photo.png").string());
                   }});
  cases.push_back({"HugeGreyPngReduced", m,
                   "a 4000x3000 one-channel PNG (a few hundred KB), reduced while read to 400x300",
                   "output: 400x300 linear RGB, the grey level kept", Expect::Result, {}, [](Digest& d) {
                     ScratchDir dir("HugeGreyPngReduced");
                     const fs::path path = dir / "grey.png";
                     capture::write_image(path.string(), cv::Mat(3000, 4000, CV_8UC1, cv::Scalar(128)));
                     const cv::Mat small = capture::load_photo_reduced(path.string(), {400, 300});
                     check(small.size() == cv::Size(400, 300) && small.type() == CV_32FC3, "400x300 CV_32FC3");
                     check(std::abs(cv::mean(small)[1] - capture::srgb_to_linear(128 / 255.f)) < 1e-4, "grey kept");
                     d.mat(small);
                   }});
  cases.push_back({"TextFileNamedPng", m, "a .png file holding a line of text", "error naming the file",
                   Expect::Error, {"notes.png"}, [](Digest&) {
                     ScratchDir dir("TextFileNamedPng");
                     write_text_file(dir / "notes.png", "this is not an image\n");
                     capture::load_photo_linear((dir / "notes.png").string());
                   }});
  cases.push_back({"RecordingGarbledManifest", m, "a recording whose recording.json is cut mid-object",
                   "error naming recording.json", Expect::Error, {"recording.json"}, [](Digest&) {
                     ScratchDir dir("RecordingGarbledManifest");
                     write_recording(dir / "rec");
                     write_text_file(dir / "rec" / "recording.json", "{\"camera\": {\"id\": \"x\"");
                     capture::load_recording(dir / "rec");
                   }});
  cases.push_back({"RecordingFileOutsideTheFolder", m,
                   "a recording whose frame file is \"../frame_000000.raw\" (path traversal)",
                   "error naming the file name", Expect::Error, {"../frame_000000.raw"}, [](Digest&) {
                     ScratchDir dir("RecordingFileOutsideTheFolder");
                     write_recording(dir / "rec");
                     fs::copy_file(dir / "rec" / "frame_000000.raw", dir / "frame_000000.raw");
                     replace_in_file(dir / "rec" / "recording.json", "\"frame_000000.raw\"", "\"../frame_000000.raw\"");
                     capture::load_recording(dir / "rec");
                   }});
  cases.push_back({"RecordingRawFileShort", m, "a recording whose raw file lost its last byte",
                   "error naming the raw file and its size", Expect::Error, {"frame_000000.raw"}, [](Digest&) {
                     ScratchDir dir("RecordingRawFileShort");
                     write_recording(dir / "rec");
                     fs::resize_file(dir / "rec" / "frame_000000.raw", 23);
                     capture::load_recording(dir / "rec");
                   }});
  cases.push_back({"SrgbEdgeOfNonFinitePixels", m, "linear pixels NaN, +Inf, -Inf, -1 and 1e30 to 8-bit sRGB",
                   "finite 8-bit pixels (NaN and negatives black, huge white)", Expect::Result, {}, [](Digest& d) {
                     const float nan = std::numeric_limits<float>::quiet_NaN(),
                                 inf = std::numeric_limits<float>::infinity();
                     cv::Mat lin(1, 5, CV_32FC3);
                     lin.at<cv::Vec3f>(0, 0) = {nan, nan, nan};
                     lin.at<cv::Vec3f>(0, 1) = {inf, inf, inf};
                     lin.at<cv::Vec3f>(0, 2) = {-inf, -inf, -inf};
                     lin.at<cv::Vec3f>(0, 3) = {-1.f, -1.f, -1.f};
                     lin.at<cv::Vec3f>(0, 4) = {1e30f, 1e30f, 1e30f};
                     const cv::Mat s = capture::linear_to_srgb8(lin);
                     check(s.at<cv::Vec3b>(0, 3) == cv::Vec3b(0, 0, 0), "negative is black");
                     check(s.at<cv::Vec3b>(0, 4) == cv::Vec3b(255, 255, 255), "huge is white");
                     d.mat(s);
                   }});
}

}  // namespace propcam::hard_cases
