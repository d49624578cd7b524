#include "common/job_budget.h"

#include <gtest/gtest.h>

#include <stdexcept>

namespace propcam::firmware {
namespace {

TEST(JobBudget, WorkingSizesAreParsedAndCheckedAgainstTheirRange) {
  EXPECT_EQ(parse_working_size("1024x768", "--working-size"), 1024L * 768L);
  EXPECT_EQ(parse_working_size("16x16", "--working-size"), 256L);
  for (const char* bad : {"", "1024", "1024x", "x768", "1024x768x2", "1024 x 768", "8x8", "20000x100", "-4x4", "axb"}) {
    SCOPED_TRACE(bad);
    try {
      parse_working_size(bad, "--working-size");
      ADD_FAILURE() << "accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("--working-size expects WxH with each side in 16..16384"), std::string::npos)
          << e.what();
    }
  }
}

TEST(JobBudget, TheDefaultWorkingSizeFitsTheDefaultMemoryWithAPiStillHeld) {
  const JobBudget defaults;
  EXPECT_TRUE(memory_budget_problem(defaults).empty());
  EXPECT_TRUE(memory_budget_problem(defaults, 2304L * 1296L).empty()) << "the Raspberry Pi board's still";
  EXPECT_NEAR(estimated_peak_mb(1024L * 768L), 411.0, 2.0) << "the measured 1024x768 composite peaked at 411-415 MB";
  EXPECT_LT(estimated_peak_mb(1L), estimated_peak_mb(2L));
}

TEST(JobBudget, AWorkingSizeOverTheMemoryBudgetNamesBothAndWhatFits) {
  JobBudget big;
  big.working_pixels = 2048L * 1536L;
  const std::string problem = memory_budget_problem(big);
  EXPECT_NE(problem.find("3.15 megapixels needs about 1119 MB"), std::string::npos) << problem;
  EXPECT_NE(problem.find("memory budget of 512 MB"), std::string::npos) << problem;
  EXPECT_NE(problem.find("work at 1.12 megapixels or less"), std::string::npos) << problem;
  EXPECT_THROW(check_memory_budget(big), std::invalid_argument);
  big.memory_mb = 2048;
  EXPECT_NO_THROW(check_memory_budget(big));
  // A held full-size photo counts too: 40 MP held is 1.2 GB.
  EXPECT_FALSE(memory_budget_problem(big, 40'000'000L).empty());
}

}  // namespace
}  // namespace propcam::firmware
