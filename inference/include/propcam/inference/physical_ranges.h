// The physical range of every number a user or a scene folder can give the
// appliance: checked where the number enters (the CLI, scene.json), so a
// value that would make nonsense (NaN pixels, a solver that cannot start)
// stops with a message naming the field and its range.
#pragma once

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace propcam::inference {

struct PhysicalRange {
  double min, max;
  const char* unit;  // "m", "px", "" ...
  bool contains(double v) const { return std::isfinite(v) && v >= min && v <= max; }
  std::string describe() const {
    std::ostringstream s;
    s << "a finite number in [" << min << ", " << max << "]" << (unit[0] ? " " : "") << unit;
    return s.str();
  }
};

// Camera above the floor or street: a table-top shot to a tall building's roof.
inline constexpr PhysicalRange kCameraHeightRange{0.05, 200.0, "m"};
// A focal length prior in pixels: from a fisheye on a tiny image to a long lens on 12 MP.
inline constexpr PhysicalRange kFocalPxRange{10.0, 1e5, "px"};
// The fitted camera response exponent (linear = 1, sRGB-like = 2.2).
inline constexpr PhysicalRange kResponseGammaRange{0.1, 10.0, ""};
// A light's intensity per channel in scene.json's units: far above any
// fitted light, far below what overflows the renderer's float sums.
inline constexpr PhysicalRange kLightIntensityRange{0.0, 1e9, ""};
inline constexpr PhysicalRange kAlbedoRange{0.0, 1.0, ""};
// A prop's height: a coin to a lamp post.
inline constexpr PhysicalRange kPropHeightRange{0.01, 20.0, "m"};
inline constexpr PhysicalRange kYawDegRange{-3600.0, 3600.0, "degrees"};
// A relight scale per light (0 turns it off).
inline constexpr PhysicalRange kLightScaleRange{0.0, 1e4, ""};
inline constexpr PhysicalRange kApertureRange{0.0, 1.0, "m"};
inline constexpr PhysicalRange kFocusDistanceRange{0.01, 1e4, "m"};

// Throws std::invalid_argument "<field> is <value>; it must be <range>".
inline void require_in_range(double value, const PhysicalRange& range, const std::string& field) {
  if (range.contains(value)) return;
  std::ostringstream s;
  s << field << " is " << value << "; it must be " << range.describe();
  throw std::invalid_argument(s.str());
}

}  // namespace propcam::inference
