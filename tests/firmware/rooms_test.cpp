// The firmware's rooms (firmware/README.md): each includes only rooms above
// it in the order below, so nothing includes upward and no loop forms; a
// room's flat folder stays small. Read from the sources' #include lines.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

// The order firmware/CMakeLists.txt lists them in: a room may include the rooms before it.
const std::vector<std::string> kRooms = {"common", "storage", "appliance", "worlds",
                                         "tools",  "bench",   "world_bench", "cli"};
// "~15 files" in a flat folder before a room should split.
constexpr size_t kMaxFilesPerRoom = 18;

const fs::path firmware_dir() { return fs::path(PROPCAM_SOURCE_DIR) / "firmware"; }

size_t room_rank(const std::string& room) {
  return static_cast<size_t>(std::find(kRooms.begin(), kRooms.end(), room) - kRooms.begin());
}

std::vector<std::string> firmware_includes(const fs::path& file) {
  static const std::regex include(R"re(^\s*#\s*include\s*"([a-z_]+)/[^"]+")re");
  std::vector<std::string> rooms;
  std::ifstream in(file);
  std::string line;
  std::smatch m;
  while (std::getline(in, line))
    if (std::regex_search(line, m, include)) rooms.push_back(m[1]);
  return rooms;
}

}  // namespace

TEST(FirmwareRooms, EveryFolderIsAKnownRoomOfFewFiles) {
  for (const auto& entry : fs::directory_iterator(firmware_dir())) {
    if (!entry.is_directory()) continue;
    const std::string name = entry.path().filename();
    if (name == "daemon") continue;  // propcamd: its own executable, linking no firmware code
    EXPECT_LT(room_rank(name), kRooms.size()) << name << " is not a room listed in firmware/CMakeLists.txt";
    const auto files = std::distance(fs::directory_iterator(entry.path()), fs::directory_iterator());
    EXPECT_LE(static_cast<size_t>(files), kMaxFilesPerRoom) << name;
  }
}

TEST(FirmwareRooms, NoRoomIncludesARoomBelowIt) {
  int files = 0;
  for (const std::string& room : kRooms) {
    ASSERT_TRUE(fs::is_directory(firmware_dir() / room)) << room;
    for (const auto& entry : fs::directory_iterator(firmware_dir() / room)) {
      ++files;
      for (const std::string& included : firmware_includes(entry.path())) {
        if (included == "propcam") continue;  // the modules' public headers
        ASSERT_LT(room_rank(included), kRooms.size()) << entry.path() << " includes from unknown room " << included;
        EXPECT_LE(room_rank(included), room_rank(room))
            << entry.path().lexically_relative(firmware_dir()) << " includes from " << included << ", a room below "
            << room;
      }
    }
  }
  EXPECT_GT(files, 50);
}

// The daemon links no firmware code: of the rooms it may include only the
// header-only logging.
TEST(FirmwareRooms, TheDaemonIncludesOnlyCommonLogging) {
  std::ifstream in(firmware_dir() / "daemon" / "propcamd.cpp");
  ASSERT_TRUE(in);
  std::string line;
  static const std::regex include(R"re(^\s*#\s*include\s*"([a-z_]+/[^"]+)")re");
  std::smatch m;
  while (std::getline(in, line))
    if (std::regex_search(line, m, include) && m[1].str().rfind("propcam/", 0) != 0)
      EXPECT_EQ(m[1].str(), "common/logging.h");
}
