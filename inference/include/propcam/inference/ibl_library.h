// The IBL library for out-of-view light (Karsch et al. 2014, Sec. on
// out-of-view light): annotated equirectangular HDR panoramas, indoor and
// outdoor. Entries come from Debian's blender-data panoramas (read from their
// installed path) and from panoramas our own code generates (analytic skies
// with a sun, simple lit interiors). Every annotation except indoor/outdoor of
// the Debian maps (a label, as the paper's SUN360 labels) is computed from the
// HDR: connected bright regions, their directions, solid angles, power shares
// and a distance class.
//
// Panoramas use the EnvironmentLight convention: CV_32FC3 linear RGB, the
// centre column is -Z, columns increase toward +X (the seam is +Z), row 0 is
// +Y (world Y up).
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace propcam::inference {

enum class SceneKind { Indoor, Outdoor };
enum class LightDistance { Close, Medium, Far, Infinite };

const char* to_string(SceneKind kind);
const char* to_string(LightDistance distance);

struct IblLightRegion {
  Eigen::Vector3d direction = Eigen::Vector3d::UnitY();  // power-weighted centroid, unit length
  double solid_angle_sr = 0;
  double power_share = 0;  // of the whole panorama's power (luminance x solid angle)
  LightDistance distance = LightDistance::Infinite;
};

struct IblEntry {
  std::string name;
  std::string source;  // "blender-data:<file>" or "procedural:<generator and parameters>"
  SceneKind kind = SceneKind::Indoor;
  cv::Mat latlong;     // CV_32FC3, finite and non-negative
  std::vector<IblLightRegion> lights;  // brightest first
};

struct IblLibrary {
  std::vector<IblEntry> entries;
};

// Negative and non-finite texels (lossy DWAB compression leaves small
// negative values; NaN/Inf are corrupt) become 0. Throws std::invalid_argument
// unless the input is a non-empty 3-channel float image.
cv::Mat sanitize_latlong(const cv::Mat& latlong);

// Area-averaged to width x width/2 (the panorama is sanitized first).
cv::Mat downsample_latlong(const cv::Mat& latlong, int width);

// Connected regions (wrapping around the seam) brighter than the threshold
// below, with their centroid direction, solid angle, power share and a
// distance class (see ibl_library.cpp for the heuristic). Regions with less
// than kMinPowerShare of the power are dropped. Brightest first.
std::vector<IblLightRegion> find_light_regions(const cv::Mat& latlong, SceneKind kind);

// Analytic clear sky: zenith-to-horizon gradient, circumsolar glow that widens
// with turbidity (2 = very clear .. 10 = hazy), a sun disc, and a grey ground.
cv::Mat procedural_sky(double sun_elevation_deg, double sun_azimuth_deg, double turbidity, int width);
// The sun's direction for procedural_sky (azimuth 0 = -Z, 90 = +X).
Eigen::Vector3d sun_direction(double sun_elevation_deg, double sun_azimuth_deg);

// A box room seen from its middle at 1.5 m: diffuse walls lit by emissive
// ceiling panels (and optionally a window with sky light), ray cast per texel.
struct ProceduralRoom {
  double width_m = 5, depth_m = 4, height_m = 2.7;
  std::vector<Eigen::Vector2d> panel_xz;  // centres of 0.6 m square ceiling panels (room-centred)
  double panel_radiance = 30;
  bool window = false;  // on the -Z wall
  Eigen::Vector3d wall_albedo{0.6, 0.55, 0.5};
};
ProceduralRoom procedural_room_params(unsigned seed);
cv::Mat render_procedural_room(const ProceduralRoom& room, int width);
// Unit directions from the camera to the room's panel centres.
std::vector<Eigen::Vector3d> panel_directions(const ProceduralRoom& room);

struct IblLibraryOptions {
  int width = 256;  // stored panoramas are width x width/2
  std::string blender_dir = "/usr/share/blender/datafiles/studiolights/world";  // skipped if absent
  int procedural_skies = 8;
  int procedural_rooms = 8;
  // Further HDR panoramas (EXR files, e.g. the @pmndrs/assets maps that
  // scripts/fetch_pmndrs_hdri.sh decodes), each with its label.
  struct ExtraPanorama {
    std::string path;
    SceneKind kind = SceneKind::Indoor;
  };
  std::vector<ExtraPanorama> extra_panoramas;
};

// "PATH=indoor" or "PATH=outdoor"; throws std::invalid_argument otherwise.
IblLibraryOptions::ExtraPanorama parse_extra_panorama(const std::string& spec);

// Half-float EXRs overflow on the sun: a texel with a +Inf channel becomes
// white at the map's brightest finite value (sanitize_latlong would make it
// black, and the sun would vanish). Other texels are untouched.
cv::Mat replace_overflowed_texels(const cv::Mat& latlong);

// Builds all entries (the Debian ones only when the folder exists).
IblLibrary build_ibl_library(const IblLibraryOptions& options);

// DIR/library.json plus one DIR/<name>.exr per entry.
void save_ibl_library(const IblLibrary& library, const std::string& dir);
// Throws std::runtime_error naming the problem for a missing, malformed or
// inconsistent library.json or a missing panorama.
IblLibrary load_ibl_library(const std::string& dir);

}  // namespace propcam::inference
