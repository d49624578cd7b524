// A hidden facade's validation, apart from the search and the mesh: the
// scene file's loader (and its fuzz target) need only this.
#include <cmath>
#include <stdexcept>

#include "propcam/inference/hidden_facades.h"
#include "propcam/inference/physical_ranges.h"

namespace propcam::inference {

void HiddenFacade::validate() const {
  constexpr double kUnitTolerance = 1e-3;
  if (!normal.allFinite() || !albedo.allFinite() ||
      !std::isfinite(offset + bottom_m + top_m + seen_min + seen_max + along_min + along_max))
    throw std::runtime_error("hidden facade: non-finite number");
  if (std::abs(normal.norm() - 1.0) > kUnitTolerance || std::abs(normal.y()) > kUnitTolerance)
    throw std::runtime_error("hidden facade: the normal must be horizontal and unit");
  if (!(top_m > bottom_m) || top_m - bottom_m > kMaxFacadeHeightM || std::abs(offset) > kMaxFacadeSpanM)
    throw std::runtime_error("hidden facade: bad height or offset");
  if (!(along_min <= seen_min && seen_min <= seen_max && seen_max <= along_max) || along_max - along_min > kMaxFacadeSpanM)
    throw std::runtime_error("hidden facade: bad extent along it");
  if (pixels < 0) throw std::runtime_error("hidden facade: negative pixel count");
  for (int c = 0; c < 3; ++c) require_in_range(albedo[c], kAlbedoRange, "hidden facade albedo");
}

}  // namespace propcam::inference
