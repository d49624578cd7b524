// Boards by name over several folders: the administrator's before the
// shipped ones; an unknown name lists the boards of all of them.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "common/board_lookup.h"

namespace {

namespace fs = std::filesystem;
using propcam::firmware::BoardConfigError;
using propcam::firmware::load_board;

const fs::path kSource = PROPCAM_SOURCE_DIR;

TEST(BoardLookup, TheAdministratorsBoardWinsAndAnUnknownNameListsAll) {
  const fs::path admin = fs::path(::testing::TempDir()) / "propcam_board_lookup" / "etc_boards";
  fs::remove_all(admin.parent_path());
  fs::create_directories(admin / "rpi");
  // The administrator's rpi: the shipped one with another description.
  std::ifstream in(kSource / "board/rpi/board.json");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string from = "\"description\": \"";
  text.insert(text.find(from) + from.size(), "Ours: ");
  std::ofstream(admin / "rpi/board.json") << text;

  const fs::path shipped = kSource / "board";
  EXPECT_EQ(load_board({admin, shipped}, "rpi").description.rfind("Ours: ", 0), 0u);
  EXPECT_EQ(load_board({admin, shipped}, "rpi").file, admin / "rpi/board.json");
  EXPECT_EQ(load_board({admin, shipped}, "virtual").file, shipped / "virtual/board.json");
  EXPECT_EQ(load_board({admin.parent_path() / "absent", shipped}, "rpi").file, shipped / "rpi/board.json");
  try {
    load_board({admin, shipped}, "nope");
    ADD_FAILURE() << "an unknown board must throw";
  } catch (const BoardConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("no board \"nope\" in " + admin.string() + ", " + shipped.string()), std::string::npos) << what;
    EXPECT_NE(what.find("qemu, rpi, usb-webcam, virtual"), std::string::npos) << what;
  }
  EXPECT_THROW(load_board({admin, shipped}, "../rpi"), BoardConfigError);
  fs::remove_all(admin.parent_path());
}

}  // namespace
