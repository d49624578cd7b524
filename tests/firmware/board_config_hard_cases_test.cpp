// Board files nobody should write but someone will: garbage, truncated,
// huge, deeply nested, mis-encoded, randomly corrupted. Each must either load
// or fail with a BoardConfigError naming the file: never crash, never hang,
// never throw anything else.
#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <unistd.h>

#include "common/board_config.h"

namespace propcam::firmware {
namespace {
namespace fs = std::filesystem;

const fs::path kVirtual = fs::path(PROPCAM_SOURCE_DIR) / "board" / "virtual" / "board.json";

std::string read_all(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

class BoardHardCases : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("propcam_board_hard_" + std::to_string(getpid()) + "_" + info->name()) / "virtual";
    fs::create_directories(dir_);
    file_ = dir_ / "board.json";
    good_ = read_all(kVirtual);
  }
  void TearDown() override { fs::remove_all(dir_.parent_path()); }

  void write(const std::string& text) { std::ofstream(file_, std::ios::binary | std::ios::trunc) << text; }

  // "" when the file loads, else the error text (which must name the file).
  std::string outcome(const std::string& text) {
    write(text);
    try {
      load_board_file(file_);
      return "";
    } catch (const BoardConfigError& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind(file_.string() + ": ", 0), 0u) << what;
      return what;
    }
  }

  fs::path dir_, file_;
  std::string good_;
};

TEST_F(BoardHardCases, TheCopiedVirtualBoardLoads) { EXPECT_EQ(outcome(good_), ""); }

TEST_F(BoardHardCases, EveryTruncationFailsCleanly) {
  // Cutting a valid file anywhere leaves either invalid JSON or (cut after
  // the final brace) the whole file.
  int rejected = 0;
  for (std::size_t n = 0; n < good_.size(); ++n) {
    const std::string err = outcome(good_.substr(0, n));
    const bool only_whitespace_lost = good_.find_first_not_of(" \n\r\t", n) == std::string::npos;
    if (only_whitespace_lost) {
      EXPECT_EQ(err, "") << n;
    } else {
      EXPECT_NE(err.find("not valid JSON"), std::string::npos) << "cut at " << n << ": " << err;
      ++rejected;
    }
  }
  EXPECT_GT(rejected, 500);
}

TEST_F(BoardHardCases, GarbageBytes) {
  std::mt19937 rng(12345);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int round = 0; round < 200; ++round) {
    std::string junk(1 + round * 7, '\0');
    for (char& c : junk) c = static_cast<char>(byte(rng));
    EXPECT_NE(outcome(junk), "") << round;
  }
  EXPECT_NE(outcome(std::string(1000, '\0')).find("not valid JSON"), std::string::npos);
  EXPECT_NE(outcome("\x89PNG\r\n\x1a\n").find("not valid JSON"), std::string::npos);
}

TEST_F(BoardHardCases, HugeFilesAreRefusedBeforeParsing) {
  std::string huge = good_;
  huge.insert(huge.find('{') + 1, "\"description\": \"" + std::string(kMaxBoardFileBytes, 'x') + "\",");
  const std::string err = outcome(huge);
  EXPECT_NE(err.find("too large"), std::string::npos) << err.substr(0, 200);
}

TEST_F(BoardHardCases, DeepNestingNeitherCrashesNorLoads) {
  const int depth = 200000;
  const std::string nested = std::string(depth, '[') + std::string(depth, ']');
  EXPECT_NE(outcome(nested).find("must be a JSON object, not an array"), std::string::npos);
  std::string in_comment = good_;
  in_comment.insert(in_comment.find('{') + 1, "\"comment\": " + nested + ",");
  EXPECT_NE(outcome(in_comment).find("/comment: must be a string"), std::string::npos);
  EXPECT_NE(outcome(std::string(depth, '{')).find("not valid JSON"), std::string::npos);
}

TEST_F(BoardHardCases, EncodingAndNumberEdges) {
  std::string bad_utf8 = good_;
  bad_utf8.replace(bad_utf8.find("Runs anywhere"), 4, "\xff\xfe\xc3(");
  EXPECT_NE(outcome(bad_utf8).find("not valid JSON"), std::string::npos);
  // A UTF-8 byte order mark is tolerated, as editors add one.
  EXPECT_EQ(outcome("\xEF\xBB\xBF" + good_), "");

  auto with_height = [&](const std::string& number) {
    std::string t = good_;
    const auto at = t.find("1.5");
    return t.replace(at, 3, number);
  };
  EXPECT_EQ(outcome(with_height("1.5e0")), "");
  const std::string inf = outcome(with_height("1e400"));
  EXPECT_TRUE(inf.find("/camera_mount_height_m: must be finite") != std::string::npos ||
              inf.find("not valid JSON") != std::string::npos) << inf;
  EXPECT_NE(outcome(with_height("-0.0")).find("out of range"), std::string::npos);

  auto with_debounce = [&](const std::string& number) {
    std::string t = good_;
    const auto at = t.find("\"debounce_ms\": 20");
    return t.replace(at, 17, "\"debounce_ms\": " + number);
  };
  EXPECT_NE(outcome(with_debounce("18446744073709551615")).find("out of range [0, 200]"), std::string::npos);
  EXPECT_NE(outcome(with_debounce("-9223372036854775808")).find("out of range [0, 200]"), std::string::npos);
  EXPECT_NE(outcome(with_debounce("99999999999999999999999")).find("must be an integer"), std::string::npos);
  EXPECT_NE(outcome(with_debounce("true")).find("must be an integer, not a boolean"), std::string::npos);
  EXPECT_NE(outcome(with_debounce("null")).find("must be an integer, not null"), std::string::npos);
}

TEST_F(BoardHardCases, NotAFile) {
  fs::remove(file_);
  fs::create_directory(file_);
  try {
    load_board_file(file_);
    ADD_FAILURE() << "a folder loaded as a board file";
  } catch (const BoardConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("no such board file"), std::string::npos) << e.what();
  }
}

TEST_F(BoardHardCases, RandomCorruptionOnlyEverGivesBoardErrors) {
  std::mt19937 rng(777);
  int loaded = 0, refused = 0;
  for (int round = 0; round < 3000; ++round) {
    std::string t = good_;
    const int edits = 1 + static_cast<int>(rng() % 4);
    for (int e = 0; e < edits; ++e) {
      const std::size_t at = rng() % t.size();
      switch (rng() % 3) {
        case 0: t[at] = static_cast<char>(rng() % 256); break;
        case 1: t.erase(at, 1 + rng() % 8); break;
        default: t.insert(at, 1, "{}[]\",:0x-./\\"[rng() % 13]); break;
      }
      if (t.empty()) t.push_back('{');  // (not t = "{": GCC 12 warns -Wrestrict falsely)
    }
    try {
      (outcome(t).empty() ? loaded : refused)++;
    } catch (const std::exception& e) {
      ADD_FAILURE() << "round " << round << " threw something else: " << e.what();
    }
  }
  EXPECT_GT(refused, 2000);
  SUCCEED() << loaded << " corrupted files still loaded (edits inside strings)";
}

}  // namespace
}  // namespace propcam::firmware
