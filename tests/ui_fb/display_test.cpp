#include "propcam/ui_fb/display.h"

#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

namespace propcam::ui_fb {
namespace {

namespace fs = std::filesystem;

// A fresh folder per test, removed afterwards.
class DisplayTest : public testing::Test {
 protected:
  void SetUp() override {
    const auto* info = testing::UnitTest::GetInstance()->current_test_info();
    folder_ = fs::path(testing::TempDir()) /
              ("ui_fb_" + std::string(info->name()) + "_" + std::to_string(::getpid()));
    fs::remove_all(folder_);
  }
  void TearDown() override { fs::remove_all(folder_); }

  fs::path folder_;
};

// A canvas that exercises every channel value and some text.
Canvas test_pattern(Size size) {
  Canvas canvas(size);
  for (int y = 0; y < size.height; ++y) {
    for (int x = 0; x < size.width; ++x) {
      canvas.set_pixel(x, y, {static_cast<std::uint8_t>(x * 255 / (size.width - 1)),
                              static_cast<std::uint8_t>(y * 255 / (size.height - 1)),
                              static_cast<std::uint8_t>((x * 7 + y * 13) & 0xFF)});
    }
  }
  canvas.fill_rect({5, 5, 40, 20}, {0, 0, 0});
  canvas.draw_text(8, 20, "Hi", 14, {255, 255, 255});
  return canvas;
}

// Reads a PNG with OpenImageIO into an RGB8 canvas; fails the test on any mismatch
// in size or channel count.
Canvas read_png(const fs::path& path) {
  auto input = OIIO::ImageInput::open(path.string());
  if (!input) throw std::runtime_error("cannot open " + path.string() + ": " + OIIO::geterror());
  const OIIO::ImageSpec& spec = input->spec();
  EXPECT_EQ(spec.nchannels, 3);
  Canvas image(spec.width, spec.height);
  const bool ok = input->read_image(0, 0, 0, 3, OIIO::TypeDesc::UINT8, image.pixels().data);
  EXPECT_TRUE(ok) << input->geterror();
  input->close();
  return image;
}

bool same_pixels(const Canvas& a, const Canvas& b) {
  return a.size() == b.size() && cv::countNonZero(a.pixels().reshape(1) != b.pixels().reshape(1)) == 0;
}

std::vector<std::string> folder_listing(const fs::path& folder) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(folder)) names.push_back(entry.path().filename());
  std::sort(names.begin(), names.end());
  return names;
}

TEST_F(DisplayTest, FileDisplayWritesAPngEqualToTheCanvas) {
  FileDisplayOptions options;
  options.size = {64, 48};
  options.snapshot_path = folder_ / "screen.png";  // folder created on demand
  FileDisplay display(options);
  EXPECT_EQ(display.size(), (Size{64, 48}));

  const Canvas canvas = test_pattern(display.size());
  display.present(canvas);
  EXPECT_EQ(display.frames_presented(), 1);
  EXPECT_EQ(display.last_snapshot(), folder_ / "screen.png");
  EXPECT_TRUE(same_pixels(read_png(folder_ / "screen.png"), canvas));
  // The temporary file was renamed away, not left behind.
  EXPECT_EQ(folder_listing(folder_), std::vector<std::string>{"screen.png"});

  // A second frame replaces the fixed-name snapshot.
  Canvas second(display.size());
  second.fill({1, 2, 3});
  display.present(second);
  EXPECT_TRUE(same_pixels(read_png(folder_ / "screen.png"), second));
  EXPECT_EQ(folder_listing(folder_), std::vector<std::string>{"screen.png"});
}

TEST_F(DisplayTest, FileDisplayPacksWithStrideAndShowsRgb565Quantisation) {
  FileDisplayOptions options;
  options.size = {40, 30};
  options.format = FramebufferFormat::rgb565();
  options.line_length = 96;  // 80 bytes of pixels, 16 of padding
  options.snapshot_path = folder_ / "frame.png";
  options.numbered = true;
  FileDisplay display(options);

  const Canvas canvas = test_pattern(display.size());
  display.present(canvas);
  display.present(canvas);
  EXPECT_EQ(folder_listing(folder_), (std::vector<std::string>{"frame_000001.png", "frame_000002.png"}));

  // The framebuffer holds RGB565 words at the given stride.
  ASSERT_EQ(display.framebuffer().size(), 96u * 30);
  const PixelPacker packer(FramebufferFormat::rgb565());
  const std::uint32_t word = packer.pack(canvas.pixel(39, 29));
  EXPECT_EQ(display.framebuffer()[29 * 96 + 39 * 2], word & 0xFF);
  EXPECT_EQ(display.framebuffer()[29 * 96 + 39 * 2 + 1], word >> 8);

  // The snapshot shows the screen (quantised), not the original canvas.
  const Canvas snapshot = read_png(folder_ / "frame_000002.png");
  EXPECT_TRUE(same_pixels(snapshot, display.screen_contents()));
  EXPECT_FALSE(same_pixels(snapshot, canvas));
  EXPECT_EQ(snapshot.pixel(39, 29), packer.unpack(word));
}

TEST_F(DisplayTest, FileDisplayRejectsAWrongSizedCanvas) {
  FileDisplayOptions options;
  options.size = {32, 32};
  options.snapshot_path = folder_ / "screen.png";
  FileDisplay display(options);
  EXPECT_THROW(display.present(Canvas(31, 32)), std::invalid_argument);
  EXPECT_THROW(FileDisplay({{0, 10}, FramebufferFormat::rgb565(), 0, folder_ / "x.png", false}),
               std::invalid_argument);
  EXPECT_THROW(FileDisplay({{10, 10}, FramebufferFormat::rgb565(), 19, folder_ / "x.png", false}),
               std::invalid_argument);
}

// Expects FbdevDisplay(path) to throw std::runtime_error mentioning `fragment`.
void expect_fbdev_error(const fs::path& path, const std::string& fragment) {
  try {
    FbdevDisplay display(path);
    ADD_FAILURE() << "opening " << path << " as a framebuffer should fail";
  } catch (const std::runtime_error& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find(fragment), std::string::npos) << message;
    EXPECT_NE(message.find(path.string()), std::string::npos) << message;
  }
}

TEST_F(DisplayTest, FbdevDisplayRefusesThingsThatAreNotFramebuffers) {
  fs::create_directories(folder_);
  const fs::path regular_file = folder_ / "fake_fb0";
  std::ofstream(regular_file) << std::string(4096, '\0');
  expect_fbdev_error(regular_file, "not a framebuffer");
  expect_fbdev_error(folder_ / "missing_fb", "cannot open");
  if (fs::exists("/dev/null")) expect_fbdev_error("/dev/null", "not a framebuffer");
}

TEST(FbdevDisplay, PresentsOnDevFb0) {
  if (!fs::exists("/dev/fb0")) GTEST_SKIP() << "/dev/fb0 does not exist on this machine";
  FbdevDisplay display("/dev/fb0");
  const Size size = display.size();
  ASSERT_GT(size.width, 0);
  ASSERT_GT(size.height, 0);
  Canvas canvas(size);
  canvas.fill({20, 20, 40});
  canvas.draw_text(10, size.height / 2, "PropCam ui_fb test", std::max(12, size.height / 20),
                   {255, 255, 255});
  display.present(canvas);
  display.present(canvas);  // exercises both pages when double-buffered
  EXPECT_FALSE(display.name().empty());
  EXPECT_THROW(display.present(Canvas(size.width + 1, size.height)), std::invalid_argument);
}

}  // namespace
}  // namespace propcam::ui_fb
