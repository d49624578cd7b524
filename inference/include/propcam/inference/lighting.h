// Materials and lighting (first cut): albedo by dividing out smooth shading,
// visible light sources from bright regions lifted to 3D quads, out-of-view
// light as the photo wrapped onto a sphere (Khan et al. 2006), and light
// intensities fitted so that a render of the empty scene matches the photo
// (the paper's basis-render optimisation with its camera-response term).
#pragma once

#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "propcam/inference/albedo.h"
#include "propcam/inference/hidden_facades.h"
#include "propcam/inference/ibl_ranking.h"
#include "propcam/inference/intensity_fit.h"
#include "propcam/inference/light_classifier.h"
#include "propcam/inference/lit_wall_lamp.h"
#include "propcam/inference/room_enclosure.h"
#include "propcam/inference/scene_model.h"
#include "propcam/inference/sky.h"
#include "propcam/inference/sun_choice.h"
#include "propcam/inference/sun_from_shadows.h"
#include "propcam/inference/sun_patch.h"
#include "propcam/render/camera.h"

namespace propcam::inference {

struct LightingOptions {
  int max_area_lights = 4;
  double bright_fraction_of_max = 0.8;  // a source is at least this bright relative to the brightest pixel
  double min_source_luminance = 0.6;    // and at least this bright (linear)
  double min_source_area_fraction = 2e-4;
  double min_source_height_m = 0.1;     // bright regions lower than this lie on the floor: lit, not lamps
  // The visible-light classifier (light_classifier.h): empty, the committed
  // model; "none", the brightness threshold alone.
  std::string light_classifier;
  LightClassifierOptions classifier;
  // Outdoors, the classifier's vote share that makes a source, when set
  // (else classifier.threshold). Unset by default: the false sources
  // outdoors are sunlit facades the forest votes for at over 70%, and at 90%
  // precision on the Blender world's tune split moves 0.32 -> 0.33 only
  // (`propcam bench worlds --sweeps outdoor_sources`; docs/visible_lights.md).
  std::optional<double> outdoor_source_threshold;
  int environment_width = 128;          // equirectangular, height = width/2
  int fit_width = 160;                  // basis renders' resolution
  int fit_samples_per_pixel = 8;
  int fit_bounces = 2;
  // The intensity and camera-response fit (the paper's priors and weights).
  IntensityFitOptions fit;
  int max_fit_pixels = 512;             // fit pixels, evenly spread over the usable ones
  double max_light_tint = 4.0;          // per-channel balance of the fitted lights, relative to their luminance
  // ... and each channel's tint between neutral and the photo's own cast
  // (`propcam bench worlds --sweeps colour` turns it off; docs/camera_match.md).
  bool tint_within_photo_cast = true;
  // Out-of-view source hypotheses the fit chooses among (and prunes): a grid
  // of ceiling panels indoors, sun directions outdoors.
  int ceiling_grid = 3;                 // n x n panels
  double ceiling_panel_m = 0.6;
  int sun_azimuths = 8;
  std::vector<double> sun_elevations_deg = {25.0, 55.0};
  // Out-of-view light from the ranked IBL library (ibl_ranking.h): the light
  // regions of the best-ranked panoramas, turned so that the matched view
  // looks where the photo looks, join the candidates. `ibl_ranker` empty: the
  // committed ranker; "none": no ranking. `ibl_candidates` panoramas (< 0:
  // by scene class, below; 0: none), each with at most
  // `max_lights_per_ibl` of its brightest regions.
  std::string ibl_ranker;
  int ibl_candidates = -1;
  // Used when ibl_candidates < 0. The paper takes 3 outdoors "to improve the
  // odds of predicting the correct sun"; on the generator's streets the
  // extra suns were chosen and were wrong (`propcam bench lighting --sweeps
  // ibl`: direction 72 against 64 degrees), so outdoors takes 1 as well.
  int ibl_candidates_indoor = 1, ibl_candidates_outdoor = 1;
  int max_lights_per_ibl = 3;
  bool keep_hypotheses = true;  // the grid/sun hypotheses stay candidates beside the ranked lights
  // Outdoors the seen sky's radiance is a measurement: it lights the upper
  // hemisphere at weight 1, and so it fixes what the albedo's scale (unknown
  // from the photo alone) must be. With this on, the fit weighs the sky too;
  // its weight w becomes the albedo's scale and every other light is divided
  // by w, so the sky stays at its measured radiance. Off, the albedo keeps
  // its assumed mean (AlbedoOptions::mean_albedo) and the sky is held at 1:
  // on dark streets the sky alone then over-explains the photo and the sun
  // comes out weak (`propcam bench lighting --sweeps sky`).
  bool albedo_scale_from_sky = true;
  // The albedo's scale the sky may set keeps the mean albedo of the surfaces
  // the fit sees at or above this (streets and cities measure 0.1-0.25).
  // Below it the fit trades a darker albedo for a brighter sun, up to 3x the
  // true one, and the prop gets that sun (`propcam bench lighting --streets
  // 100 --sweeps sun_strength`; docs/streets_sun.md).
  double min_mean_albedo = 0.15;
  // Outdoors, weigh only the sun candidate the photo calls for (sun_choice.h);
  // off, the fit weighs them all and keeps the one that alone fits best.
  bool sun_from_shading = true;
  SunChoiceOptions sun_choice;
  // Outdoors under a seen sky, the sun is not a fixed set of hypotheses but
  // searched for (sun_from_shadows.h): the direction whose cast shadows on
  // the scene's geometry explain the photo, and its strength against the sky
  // from the shadows' contrast. The ranked panoramas' suns join the search.
  // The fit then weighs sky and sun together, at that ratio. Off: the
  // hypotheses above, chosen by sun_from_shading. Off by default: the search
  // needs an albedo that keeps the shadows out, and the estimated one does
  // not (`propcam bench lighting --sweeps sun`; docs/streets_sun.md).
  bool sun_from_shadows = false;
  // With the search on: true, the search's sun must pass its test and is
  // weighed with the sky at the ratio its shadows set; false, the best
  // searched direction is always a candidate and the fit weighs it alone.
  bool sun_strength_from_shadows = true;
  SunFromShadowsOptions sun_search;
  // Outdoors, the facades the depth map shows are continued out of the frame
  // (hidden_facades.h) for the basis renders and, through the scene model,
  // the composite: the buildings beside and behind the camera shade the near
  // street. Off by default: with the sun the shading picks today, their
  // shadows cost more than they give (`propcam bench lighting --sweeps
  // facades`: streets composite 0.589 -> 0.692; docs/streets_sun.md).
  bool hidden_facades = false;
  HiddenFacadeOptions facades;
  // Indoors, the room is closed around what the photo shows and the lights
  // the fit may use (room_enclosure.h) for the basis renders and, through
  // the scene model, the composite: light reaches the prop from the room's
  // lamps and walls, not from an environment pouring in behind the camera.
  // Off by default: it moves the light's direction toward the truth on all
  // three worlds (Blender tune rooms 66.5 -> 60.5 degrees, panoramas 58.7 ->
  // 52.3), but the composite's SSIM drops (Blender 0.72 -> 0.70, own 0.71 ->
  // 0.69) with the noise of the closed room's longer paths at 64 spp, and a
  // composite takes 1.6x the time (`propcam bench worlds --sweeps
  // enclosure`; docs/room_enclosure.md).
  bool enclose_room = false;
  RoomEnclosureOptions enclosure;
  // Indoors, a sharp-edged sun patch on the floor (sun_patch.h) is taken
  // for the sun through a window out of view: a sun that reaches the room
  // only through a window above the patch joins the candidates, and the
  // patch's light is taken out of the albedo the fit (and the scene) use.
  // Off by default: on photos nobody tuned for it fires on bright furniture
  // and lit walls the depth puts on the floor more often than on sun
  // patches (Blender fresh held set: 3 patches found, none of them sun;
  // panoramas' diffuse sphere si-RMSE 0.170 -> 0.183; `propcam bench worlds
  // --sweeps sun_patch`; docs/sun_patch.md).
  bool sun_from_patch = false;
  SunPatchOptions sun_patch;
  // Indoors, a lamp out of view where the falloff of the walls' and the
  // ceiling's shading points (lit_wall_lamp.h) joins the candidates as a
  // small spherical light; the fit weighs it. Off by default: it helps our
  // own world's rooms (direction 21.4 -> 18.6 degrees) but not Blender's
  // lamp-lit rooms (55.4 -> 55.5, composite 0.0713 -> 0.0721), and never
  // fires on the fresh held set (`propcam bench worlds --sweeps
  // lit_walls`; docs/lit_wall_lamp.md).
  bool lamp_from_lit_walls = false;
  LitWallLampOptions lit_wall_lamp;
  uint64_t seed = 11;
};

struct LightingEstimate {
  std::vector<LightSource> lights;  // intensities fitted
  cv::Mat source_mask;              // CV_8U, 255 on detected source pixels
  std::vector<HiddenFacade> hidden_facades;  // outdoors: the occluders the basis renders had (LightingOptions::hidden_facades)
  RoomEnclosure enclosure;                   // indoors: the room's box the basis renders had (LightingOptions::enclose_room)
  std::vector<Window> windows;               // where lights marked through_windows enter (a sun patch's sun)
  cv::Mat albedo;                            // when not empty: the albedo the lights were fitted with, to replace the one passed in
  std::vector<StageReport> reports; // sources, environment, intensity fit
  // Camera response: encoded = linear^(1/gamma), fitted with the intensities
  // (SceneModel::gamma). Light intensities are in the units of the photo
  // linearised with it.
  double gamma = 2.2;
  // The factor the albedo passed in must be multiplied by for these light
  // intensities (LightingOptions::albedo_scale_from_sky); 1 when unknown.
  double albedo_scale = 1.0;
};

// What the geometry stage saw that the IBL ranking's features use (empty: unknown).
struct GeometryCues {
  cv::Mat orientation;  // CV_8U SurfaceOrientation labels
  cv::Mat sky_mask;     // CV_8U, the sky detector's mask (indoors too)
  cv::Mat normals;      // CV_32FC3 world-space normals at the depth's size (outdoors: hidden facades)
};

LightingEstimate estimate_lighting(const cv::Mat& photo_linear, const cv::Mat& depth, const cv::Mat& albedo,
                                   const render::PinholeCamera& camera, const std::vector<SupportPlane>& planes,
                                   bool indoor, const LightingOptions& options, const SkyEstimate* sky = nullptr,
                                   const GeometryCues& cues = {});

// Candidate sources from the ranked library's light regions (unit
// intensity): suns and sky patches as far quads, lamps and windows as quads
// at their distance class, kept inside the room's planes.
struct RankedLights {
  std::vector<LightSource> lights;
  nlohmann::json matches = nlohmann::json::array();  // per panorama: name, score, matched view, lights added
};
RankedLights ranked_ibl_candidates(const IblRanker& ranker, const IblViewFeatures& features,
                                   const render::PinholeCamera& camera, const std::vector<SupportPlane>& planes,
                                   bool indoor, const LightingOptions& options);

// Candidate sources outside the frame (unit intensity), for the fit to choose from.
std::vector<LightSource> out_of_view_candidates(const render::PinholeCamera& camera,
                                                const std::vector<SupportPlane>& planes, bool indoor,
                                                const LightingOptions& options);

// Khan-style environment: directions in front of the camera see the (blurred)
// photo, directions behind it its mirror image.
cv::Mat environment_from_photo(const cv::Mat& photo_linear, const render::PinholeCamera& camera, int width);

// Outdoors: the sky seen in the photo is a radiance measurement, so the upper
// hemisphere takes the sky's colour and brightness; the lower hemisphere keeps
// the Khan wrap of the photo (the ground). (Grading it from horizon to zenith
// by the CIE standard skies was measured worse on the generator's streets:
// `propcam bench lighting`, docs/streets_sun.md.)
cv::Mat environment_with_sky(const cv::Mat& photo_linear, const render::PinholeCamera& camera, int width,
                             const SkyEstimate& sky);

}  // namespace propcam::inference
