// One budget per job: the pixels inference and rendering work at, the memory
// that may cost at its peak, and the seconds a composite may render. The
// board file sets them (board.json "budgets"), the CLI takes them as options;
// both start from the defaults below.
//
// Memory is budgeted through the working size: a job's peak grows with the
// pixels it works at (inference's maps, the renderer's buffers and the depth
// mesh's BVH), while a larger photo is read and written a band of rows at a
// time. A working size whose estimated peak is over the memory budget is
// refused before any work starts, naming both.
#pragma once

#include <string>

namespace propcam::firmware {

// About 0.8 megapixels (1024x768): inference's figures and its ≤ 3 s are
// measured at this size, and a 12 MP photo's working copy costs 9 MB.
inline constexpr long kDefaultWorkingPixels = 1024L * 768L;
inline constexpr int kMinWorkingSide = 16;  // inference's smallest photo side (kMinPhotoSide)
inline constexpr int kMaxWorkingSide = 16384;

inline constexpr long kDefaultMemoryBudgetMb = 512;
inline constexpr long kMinMemoryBudgetMb = 256, kMaxMemoryBudgetMb = 1L << 20;

// A composite's render stops refining at this, keeping what it has; the
// default is above what a 12 MP photo takes at the default quality (18–28 s)
// and leaves a chrome prop at 1024x768 (42 s) to finish.
inline constexpr double kDefaultRenderSeconds = 120.0;
inline constexpr double kMaxRenderSeconds = 24 * 3600.0;

// Peak resident memory of `propcam composite` at a working size: 267, 415
// and 749 MB at 640x480, 1024x768 and 1600x1200 (a 12 MP JPEG, the vase,
// 16 spp; docs/budgets.md), a straight line within 5 MB. Inference alone
// peaks lower, so the composite's line bounds both.
inline constexpr double kPeakFixedMb = 175.0;
inline constexpr double kPeakMbPerWorkingMegapixel = 300.0;
// A photo held whole at its full size (the appliance's still) costs its
// linear float copy (12 bytes a pixel), its 8-bit one (3) and the composite
// delivered at that size, float and 8-bit (15): 30, rounded up to 32. Photo
// files are streamed instead and hold none.
inline constexpr double kHeldPhotoBytesPerPixel = 32.0;

struct JobBudget {
  long working_pixels = kDefaultWorkingPixels;
  long memory_mb = kDefaultMemoryBudgetMb;
  double render_seconds = kDefaultRenderSeconds;
};

// "WxH" -> pixels, each side in kMinWorkingSide..kMaxWorkingSide. Throws
// std::invalid_argument naming `what` (an option or a field) and the range.
long parse_working_size(const std::string& text, const std::string& what);

// The estimated peak in MB of a job working at `working_pixels` while it
// holds `held_photo_pixels` of full-size photo (0 when streamed).
double estimated_peak_mb(long working_pixels, long held_photo_pixels = 0);

// An empty string when the job fits, else why not: the working size, its
// estimated peak and the memory budget, and what to change.
std::string memory_budget_problem(const JobBudget& budget, long held_photo_pixels = 0);

// Throws std::invalid_argument with memory_budget_problem's message.
void check_memory_budget(const JobBudget& budget, long held_photo_pixels = 0);

}  // namespace propcam::firmware
