// Runs every catalogue case twice: a Result case must give the same digest
// both times with every number finite; an Error case must throw a
// std::exception both times, with the same non-empty message naming the
// problem. Each case is its own ctest test (label hard_case).
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <fstream>
#include <map>
#include <optional>
#include <set>

#include "catalogue.h"

namespace propcam::hard_cases {
namespace {

struct Attempt {
  std::optional<std::string> error;  // the message, when it threw
  std::string digest;
  std::size_t items = 0, non_finite = 0;
};

Attempt run_once(const HardCase& c) {
  Attempt r;
  Digest d;
  try {
    c.run(d);
  } catch (const CheckFailed&) {
    throw;  // a broken expectation, not the case's error
  } catch (const std::exception& e) {
    r.error = e.what();
  }
  r.digest = d.hex();
  r.items = d.items();
  r.non_finite = d.non_finite();
  return r;
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
  return s;
}

}  // namespace

// gtest prints a parameter by its ctest name.
void PrintTo(const HardCase& c, std::ostream* os) { *os << c.module << "_" << c.name; }

namespace {

class Catalogue : public ::testing::TestWithParam<HardCase> {};

TEST_P(Catalogue, Run) {
  const HardCase& c = GetParam();
  RecordProperty("input", c.input);
  Attempt first, second;
  try {
    first = run_once(c);
    second = run_once(c);
  } catch (const CheckFailed& e) {
    FAIL() << c.name << ": " << e.what();
  }
  if (c.expect == Expect::Result) {
    ASSERT_FALSE(first.error) << c.name << " threw: " << *first.error;
    ASSERT_FALSE(second.error) << c.name << " threw on the second run: " << *second.error;
    EXPECT_GT(first.items, 0u) << "the case recorded no output";
    EXPECT_EQ(first.non_finite, 0u) << "non-finite numbers in the output";
    EXPECT_EQ(first.items, second.items);
    EXPECT_EQ(first.digest, second.digest) << "not deterministic";
  } else {
    ASSERT_TRUE(first.error) << c.name << " gave output (digest " << first.digest << ") instead of an error";
    ASSERT_TRUE(second.error) << c.name << " gave output on the second run";
    EXPECT_FALSE(first.error->empty()) << "an error without a message";
    EXPECT_EQ(*first.error, *second.error) << "the message differs between runs";
    for (const std::string& word : c.mentions)
      EXPECT_NE(lower(*first.error).find(lower(word)), std::string::npos)
          << "the message does not name '" << word << "': " << *first.error;
  }
  std::cout << "  " << c.module << "/" << c.name << ": "
            << (first.error ? "error: " + *first.error : "digest " + first.digest) << "\n";
}

INSTANTIATE_TEST_SUITE_P(HardCases, Catalogue, ::testing::ValuesIn(catalogue()),
                         [](const ::testing::TestParamInfo<HardCase>& info) {
                           return info.param.module + "_" + info.param.name;
                         });

TEST(HardCaseCatalogue, AtLeastThirtyCasesOverEveryModule) {
  const auto& cases = catalogue();
  EXPECT_GE(cases.size(), 30u);
  std::map<std::string, int> per_module;
  std::set<std::string> names;
  for (const HardCase& c : cases) {
    ++per_module[c.module];
    EXPECT_TRUE(names.insert(c.name).second) << "duplicate case name " << c.name;
    EXPECT_FALSE(c.input.empty()) << c.name;
    EXPECT_FALSE(c.outcome.empty()) << c.name;
    EXPECT_TRUE(c.run) << c.name;
    if (c.expect == Expect::Error) {
      EXPECT_FALSE(c.mentions.empty()) << c.name << ": an error case says what it names";
    }
  }
  for (const char* module : {"capture", "inference", "render", "ui_fb", "firmware"})
    EXPECT_GE(per_module[module], 3) << module;
}

// The README's table is the catalogue's index: every case is listed there.
TEST(HardCaseCatalogue, ReadmeListsEveryCase) {
  std::ifstream in(std::string(PROPCAM_SOURCE_DIR) + "/tests/hard_cases/README.md");
  ASSERT_TRUE(in) << "tests/hard_cases/README.md is missing";
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (const HardCase& c : catalogue())
    EXPECT_NE(text.find("| " + c.module + "_" + c.name + " |"), std::string::npos)
        << c.module << "_" << c.name << " is not in README.md";
}

}  // namespace
}  // namespace propcam::hard_cases
