// The panorama world: PropCam's lighting inference measured on real light.
// Views cut from the 26 CC0 HDR panoramas the project installs (8 from
// Debian's blender-data, 18 from npm @pmndrs/assets via
// scripts/fetch_pmndrs_hdri.sh) with the code `propcam view` uses, so the
// panorama itself is the true light. A probe of three spheres (diffuse
// white, rough metal, mirror) stands on the inferred floor; it is rendered
// once into the photo under the inferred scene (as `propcam composite` does)
// and once by our path tracer under the true panorama alone, and the two are
// compared per sphere (RMSE, scale-invariant RMSE), with the angular error of
// the dominant light (light_probe.h). Every trained model used on a view is
// built without that view's panorama (leave one panorama out; duplicates
// across the two sources count as one panorama). docs/panorama_world.md.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <functional>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "tools/ibl_training.h"
#include "worlds/light_probe.h"
#include "tools/light_training.h"
#include "worlds/world_scenes.h"
#include "propcam/inference/infer.h"
#include "propcam/inference/scene_model.h"
#include "propcam/render/camera.h"

namespace propcam::firmware {

// The 26: blender-data's 8 by name, then the 18 pmndrs ones as pmndrs_<name>.
std::vector<std::string> panorama_world_names();

// The light classifier's training spec of scripts/train_light_classifier.sh
// (all 26 panoramas, pmndrs ones as files under `pmndrs_dir`; the tune
// photos of the Blender world in `blender_world`, left out of the spec when
// that world does not exist).
LightTrainingSpec committed_light_training_spec(const std::string& pmndrs_dir,
                                                const std::string& blender_world = kDefaultBlenderWorldDir);
// The IBL ranker's training spec of scripts/train_ibl_ranker.sh (the library
// of blender-data's 8, the 18 pmndrs with their labels, procedural skies and rooms).
IblTrainingSpec committed_ibl_training_spec(const std::string& pmndrs_dir);


struct PanoramaWorldOptions {
  // Names (blender-data: "courtyard"; pmndrs: "pmndrs_city" or "pmndrs/city")
  // or EXR paths (a path under pmndrs_dir or blender-data's folder is that
  // panorama; any other file is a new panorama no model has seen, its class
  // from a "=indoor"/"=outdoor" suffix, else outdoor). Empty: all 26.
  std::vector<std::string> panoramas;
  int views_per_panorama = 2;  // yaws spread around the turn
  double yaw_offset_deg = 0;   // the first view's yaw
  // Pitch a little down so the floor shows: the views step from the first
  // to the last (one view: the mean).
  double pitch_first_deg = -8, pitch_last_deg = -20;
  int width = 320, height = 240;
  double horizontal_fov_deg = 60;
  int spp = 64;  // probe renders (the composite and the truth)
  bool leave_one_out = true;
  // Leave-one-out models, reused across runs (keyed by panorama and training spec).
  std::string cache_dir = "build/worlds/loo";
  // Where scripts/fetch_pmndrs_hdri.sh decodes the pmndrs panoramas (empty:
  // <source>/build/pmndrs_hdri).
  std::string pmndrs_dir;
  // The probe: three spheres in a row facing the camera.
  double sphere_radius_m = 0.1, sphere_gap_m = 0.05;
  double rough_metal_alpha = 0.09;  // GGX alpha (roughness 0.3 squared)
  double mirror_alpha = 0.0;        // clamped to kMinRoughness (1e-3) by the BSDF
  int bounces = 4;                  // both probe renders (propcam composite's default)
  // The dominant light's cube probe: this far above the middle sphere's
  // base (bench worlds' kProbeLiftM), faces and samples.
  double light_probe_lift_m = 0.05;
  int probe_face_px = 24, probe_spp = 16;
  uint64_t seed = 1;
  // Non-empty (or env PROPCAM_PANORAMA_WORLD_DEBUG): run_panorama_world
  // writes DIR/<view>.png per placed probe (photo with the scored pixels
  // outlined | estimate | truth, sRGB) for a look at what was scored.
  std::string debug_dir;
  // The leave-one-out models' training specs (empty: those of the committed
  // models, committed_light_training_spec / committed_ibl_training_spec).
  std::optional<LightTrainingSpec> light_training;
  std::optional<IblTrainingSpec> ibl_training;
  // The IBL ranker's training set: false, built once with the committed
  // classifier and scene-class references (whose training saw every
  // panorama) and reused for every panorama; true, rebuilt per panorama with
  // its leave-one-out classifier and references (about a minute each).
  bool strict_ibl_features = false;
  bool quiet = false;
};

struct PanoramaView {  // one view: a photo with its true light
  std::string panorama, name;  // e.g. "courtyard", "courtyard_yaw120"
  // The leave-one-out group: the panorama, or the name of the one it
  // duplicates ("pmndrs_sunrise" is blender-data's "sunrise").
  std::string group;
  bool indoor = true;  // the panorama's label (ibl_library.cpp, scene_reference_builder.cpp, train_ibl_ranker.sh)
  cv::Mat photo_linear;  // CV_32FC3: 8-bit quantised, sRGB-decoded (shoot_panorama_view)
  render::PinholeCamera camera;  // exact
  cv::Mat emitters;      // CV_8U 255 where exposure * radiance >= 4 (light_classifier.h panorama_views)
  double exposure = 1;   // the view's auto exposure: photo = clip(exposure * radiance)
  double yaw_deg = 0, pitch_deg = 0;
  std::string panorama_file;
  bool known = true;  // one of the 26 the committed models were trained on
};

// Throws std::runtime_error naming the panorama when a file is missing
// (pmndrs ones: saying to run scripts/fetch_pmndrs_hdri.sh) or unreadable.
std::vector<PanoramaView> make_panorama_views(const PanoramaWorldOptions& options);

// The inference options for a view: the light classifier and IBL ranker
// trained without its panorama (cached under cache_dir/<group>/), and
// scene_class_left_out set to its panorama's scene-class references (the
// k-NN skips them). Trains on first use. Without leave_one_out, or for a
// panorama none of the committed models saw, `base` unchanged.
// `report` (optional) gets what was used and how long the training took.
inference::InferenceOptions leave_one_out_options(const PanoramaView& view, const PanoramaWorldOptions& options,
                                                  inference::InferenceOptions base = {},
                                                  nlohmann::json* report = nullptr);

struct SphereScore {
  std::string material;
  double rmse = NAN, si_rmse = NAN;
  int pixels = 0;
  double mean_estimate = NAN, mean_truth = NAN;  // mean luminance (display-linear, clipped)
};

struct ProbeResult {
  bool placed = false;
  std::string why;  // why not placed
  Eigen::Vector2d at = Eigen::Vector2d::Constant(NAN);  // the pixel the probe stands on
  std::vector<SphereScore> spheres;  // diffuse, rough metal, mirror
  double si_scale = NAN;             // the one scale over all three spheres applied to the estimate
  // The Khan-style baseline (world_metrics.h) at the same spot, scored the same way.
  std::vector<SphereScore> khan_spheres;
  double khan_si_scale = NAN;
  double direction_deg = NAN;        // dominant light: estimate vs panorama, in the camera frame
  LightMoments estimate_light, true_light;  // in each one's camera frame (vector); irradiance_up in each world
  double seconds = 0;                // the two probe renders
  double light_probe_seconds = 0;    // the estimate's cube probe
  // Display-referred (sRGB-encoded, [0,1]) CV_32FC3: the composite, and the
  // photo with the truth's rendered box (spheres under the panorama) pasted in.
  cv::Mat estimate, truth;
  cv::Mat mask;             // CV_8U: 1, 2, 3 on the pixels scored for the diffuse, rough metal, mirror sphere
};

// Places the probe on the inferred floor (near the bottom centre; tries
// other pixels if the first is not a level support or the spheres leave the
// frame) and scores it. Never throws for a scene it cannot place on: placed
// = false and `why`.
ProbeResult score_light_probe(const PanoramaView& view, const inference::SceneModel& estimate,
                              const PanoramaWorldOptions& options);

// All views: leave-one-out inference, probes; {"options", "summary", "scenes": [rows]}.
// A panorama that cannot be read, or a view whose inference throws, is a
// row with "error" (the run goes on).
// `tweak` changes the inference options of every view (after the leave-one-out paths are set).
nlohmann::json run_panorama_world(const PanoramaWorldOptions& options,
                                  std::function<void(inference::InferenceOptions&)> tweak = {});
std::string format_panorama_world(const nlohmann::json& result);

}  // namespace propcam::firmware
