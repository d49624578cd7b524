// DrmDisplay: errors for things that are not DRM cards (everywhere), and a real
// modeset + page flips on the first card with a connected display (skipped where
// there is none, e.g. CI containers).
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "propcam/ui_fb/display.h"

namespace propcam::ui_fb {
namespace {

namespace fs = std::filesystem;

// The message of the std::runtime_error that opening `card` raises.
std::string open_error(const fs::path& card) {
  DrmDisplayOptions options;
  options.card = card;
  try {
    DrmDisplay display(options);
  } catch (const std::runtime_error& error) {
    return error.what();
  }
  ADD_FAILURE() << "opening " << card << " as a DRM card should fail";
  return "";
}

TEST(DrmDisplay, AMissingCardIsAnErrorNamingThePath) {
  const fs::path card = "/dev/dri/card-propcam-missing";
  const std::string message = open_error(card);
  EXPECT_NE(message.find(card.string()), std::string::npos) << message;
  EXPECT_NE(message.find("cannot open"), std::string::npos) << message;
}

TEST(DrmDisplay, DevNullIsNotADrmDevice) {
  if (!fs::exists("/dev/null")) GTEST_SKIP() << "no /dev/null";
  const std::string message = open_error("/dev/null");
  EXPECT_NE(message.find("/dev/null"), std::string::npos) << message;
  EXPECT_NE(message.find("not a DRM device"), std::string::npos) << message;
}

TEST(DrmDisplay, ARegularFileIsNotADrmDevice) {
  const fs::path file = fs::path(testing::TempDir()) / ("fake_card_" + std::to_string(::getpid()));
  std::ofstream(file) << "not a card";
  const std::string message = open_error(file);
  EXPECT_NE(message.find(file.string()), std::string::npos) << message;
  EXPECT_NE(message.find("not a DRM device (not a character device)"), std::string::npos) << message;
  fs::remove(file);
}

TEST(DrmDisplay, OnlyOneOrTwoBuffers) {
  for (int count : {0, 3, -1}) {
    DrmDisplayOptions options;
    options.card = "/dev/null";  // never opened: the count is checked first
    options.buffer_count = count;
    EXPECT_THROW(DrmDisplay{options}, std::invalid_argument) << count;
  }
}

std::vector<fs::path> openable_cards() {
  std::vector<fs::path> cards;
  std::error_code error;
  for (const auto& entry : fs::directory_iterator("/dev/dri", error)) {
    if (entry.path().filename().string().rfind("card", 0) != 0) continue;
    const int fd = ::open(entry.path().c_str(), O_RDWR | O_CLOEXEC);
    if (fd < 0) continue;
    ::close(fd);
    cards.push_back(entry.path());
  }
  std::sort(cards.begin(), cards.end());
  return cards;
}

Canvas test_pattern(Size size, int frame) {
  Canvas canvas(size);
  canvas.fill({static_cast<std::uint8_t>(40 * frame), 20, 60});
  canvas.fill_rect({size.width / 4, size.height / 4, size.width / 2, size.height / 2}, {255, 255, 255});
  return canvas;
}

// Opens the first card that can show something; skips (with why) if none can.
std::optional<DrmDisplay> open_real_display(int buffer_count, std::string& why_not) {
  const auto cards = openable_cards();
  if (cards.empty()) {
    why_not = "no /dev/dri/card* can be opened on this machine";
    return std::nullopt;
  }
  for (const fs::path& card : cards) {
    DrmDisplayOptions options;
    options.card = card;
    options.buffer_count = buffer_count;
    try {
      return std::optional<DrmDisplay>(std::in_place, options);
    } catch (const DrmDisplayUnavailable& error) {
      why_not += std::string(error.what()) + "; ";
    } catch (const std::runtime_error& error) {
      const std::string message = error.what();
      // Render-only GPUs (v3d next to vc4, etc.) have a card node without KMS.
      if (message.find("no modesetting") == std::string::npos) throw;
      why_not += message + "; ";
    }
  }
  return std::nullopt;
}

TEST(DrmDisplay, ModesetsAndPageFlipsOnARealCard) {
  std::string why_not;
  auto display = open_real_display(2, why_not);
  if (!display) GTEST_SKIP() << "no usable DRM display: " << why_not;
  const Size size = display->size();
  ASSERT_GT(size.width, 0);
  ASSERT_GT(size.height, 0);
  EXPECT_GE(display->line_length(), static_cast<std::size_t>(size.width) * display->format().bytes_per_pixel());
  EXPECT_EQ(display->buffer_count(), 2);
  for (int frame = 0; frame < 4; ++frame) display->present(test_pattern(size, frame));
  EXPECT_NE(display->name().find("drm /dev/dri/card"), std::string::npos) << display->name();
  EXPECT_THROW(display->present(Canvas(size.width + 1, size.height)), std::invalid_argument);
  std::cout << "[ INFO     ] " << display->name() << "\n";

  // Everything was released: the card can be taken again, single-buffered.
  display.reset();
  auto again = open_real_display(1, why_not);
  ASSERT_TRUE(again) << why_not;
  EXPECT_FALSE(again->page_flips());
  again->present(test_pattern(size, 1));
}

TEST(DrmDisplay, AConnectorThatDoesNotExistIsNamedInTheError) {
  const auto cards = openable_cards();
  if (cards.empty()) GTEST_SKIP() << "no /dev/dri/card* can be opened on this machine";
  DrmDisplayOptions options;
  options.card = cards.front();
  options.connector_id = 0xFFFF'FFF0u;
  try {
    DrmDisplay display(options);
    ADD_FAILURE() << "connector " << *options.connector_id << " accepted";
  } catch (const std::runtime_error& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find(cards.front().string()), std::string::npos) << message;
  }
}

}  // namespace
}  // namespace propcam::ui_fb
