// CLI11 validators for numbers with a physical range: NaN and infinities are
// refused too (CLI::Range lets NaN through, as every comparison with it is false).
#pragma once

#include <CLI/CLI.hpp>

#include "propcam/inference/physical_ranges.h"

namespace propcam::firmware {

inline CLI::Validator within(const inference::PhysicalRange& range) {
  return CLI::Validator(
      [range](std::string& text) -> std::string {
        double value = 0;
        if (!CLI::detail::lexical_cast(text, value)) return "'" + text + "' is not a number";
        if (!range.contains(value)) return "'" + text + "' is out of range: it must be " + range.describe();
        return {};
      },
      range.describe());
}

}  // namespace propcam::firmware
