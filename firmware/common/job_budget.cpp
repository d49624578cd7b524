#include "common/job_budget.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace propcam::firmware {

long parse_working_size(const std::string& text, const std::string& what) {
  int w = 0, h = 0;
  char x = 0, extra = 0;
  const bool parsed = std::sscanf(text.c_str(), "%d%c%d%c", &w, &x, &h, &extra) == 3 && x == 'x';
  if (!parsed || w < kMinWorkingSide || h < kMinWorkingSide || w > kMaxWorkingSide ||
      h > kMaxWorkingSide)
    throw std::invalid_argument(what + " expects WxH with each side in " + std::to_string(kMinWorkingSide) +
                                ".." + std::to_string(kMaxWorkingSide) + ", got '" + text + "'");
  return static_cast<long>(w) * h;
}

double estimated_peak_mb(long working_pixels, long held_photo_pixels) {
  return kPeakFixedMb + kPeakMbPerWorkingMegapixel * static_cast<double>(working_pixels) / 1e6 +
         kHeldPhotoBytesPerPixel * static_cast<double>(held_photo_pixels) / (1024.0 * 1024.0);
}

std::string memory_budget_problem(const JobBudget& budget, long held_photo_pixels) {
  const double peak = estimated_peak_mb(budget.working_pixels, held_photo_pixels);
  if (peak <= static_cast<double>(budget.memory_mb)) return {};
  // The largest working size that fits, for the message.
  const double spare_mb = static_cast<double>(budget.memory_mb) - estimated_peak_mb(0, held_photo_pixels);
  const double fitting_megapixels = std::max(0.0, spare_mb / kPeakMbPerWorkingMegapixel);
  char text[320];
  std::snprintf(text, sizeof text,
                "a working size of %.2f megapixels needs about %.0f MB at its peak%s, over the memory budget of %ld MB: "
                "work at %.2f megapixels or less, or raise the budget",
                static_cast<double>(budget.working_pixels) / 1e6, peak,
                held_photo_pixels > 0 ? " with the full-size photo held" : "", budget.memory_mb, fitting_megapixels);
  return text;
}

void check_memory_budget(const JobBudget& budget, long held_photo_pixels) {
  if (std::string problem = memory_budget_problem(budget, held_photo_pixels); !problem.empty())
    throw std::invalid_argument(problem);
}

}  // namespace propcam::firmware
