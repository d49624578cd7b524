// Test helper: what a folder holds after an atomic save.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

namespace propcam::inference {

// The folder holds exactly these files (no temporary left behind).
inline void expect_only_files(const std::string& dir, std::vector<std::string> names) {
  std::vector<std::string> found;
  for (const auto& e : std::filesystem::directory_iterator(dir)) found.push_back(e.path().filename().string());
  std::sort(found.begin(), found.end());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(found, names) << dir;
}

}  // namespace propcam::inference
