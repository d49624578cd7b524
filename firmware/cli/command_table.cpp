#include "cli/command_table.h"

#include "bench/bench.h"
#include "bench/bench_camera.h"
#include "bench/bench_geometry.h"
#include "bench/bench_lighting.h"
#include "bench/bench_render.h"
#include "bench/bench_scene_class.h"
#include "bench/bench_transfer.h"
#include "cli/capture_commands.h"
#include "cli/export_commands.h"
#include "cli/photo_commands.h"
#include "cli/run_command.h"
#include "cli/scene_commands.h"
#include "tools/depth_database_builder.h"
#include "tools/ibl_training.h"
#include "tools/light_training.h"
#include "tools/scene_reference_builder.h"
#include "world_bench/bench_worlds.h"

namespace propcam::firmware {

std::vector<Command> propcam_commands() {
  constexpr CommandGroup User = CommandGroup::User, Developer = CommandGroup::Developer;
  constexpr NeedsModels kInfers = NeedsModels::Yes, kNoModels = NeedsModels::No;
  // Every bench row infers or may: the models are checked before any starts.
  return {
      // What a user of the camera does.
      command<InferArgs>("infer", "Infer the scene model (camera, depth, albedo, lights) of a photo", User, kInfers,
                         add_infer_options, run_infer_command),
      command<CompositeArgs>("composite", "Place a prop in a photo and render the composite", User, kInfers,
                             add_composite_options, run_composite_command),
      command<PropsArgs>("props", "List the preset props (and render their thumbnails)", User, kNoModels,
                         add_props_options, run_props_command),
      command<RunArgs>("run", "Run the appliance on a board (the virtual board plays a button script)", User, kInfers,
                       add_run_options, run_run_command),
      command<CamerasArgs>("cameras", "List the cameras (libcamera, V4L2) and the replay recordings, with formats",
                           User, kNoModels, add_cameras_options, run_cameras_command),
      command<ShootArgs>("shoot", "Take a still: let exposure settle, lock it, capture, write an image", User,
                         kNoModels, add_shoot_options, run_shoot_command),
      command<RecordArgs>("record", "Record raw camera frames with their format and metadata (a replay camera)", User,
                          kNoModels, add_record_options, run_record_command),
      command<ExportArgs>("export", "Export images as composites to the USB stick, through the spool", User, kNoModels,
                          add_export_options, run_export_command),
      command<SpoolArgs>("spool", "List the exports waiting in the spool; --flush moves them to the stick", User,
                         kNoModels, add_spool_options, run_spool_command),
      command<CalibrateVignettingArgs>(
          "calibrate-vignetting",
          "Fit the lens's fall-off toward the corners from flat-field photos (for board.json and --vignetting)", User,
          kNoModels, add_calibrate_vignetting_options, run_calibrate_vignetting_command),
      command<ConsoleArgs>("console", "The VT under the display: its mode, or back to text mode (--restore)", User,
                           kNoModels, add_console_options, run_console_command),

      // Development: fixtures, the renderer alone, benches, training and data builders.
      command<ViewArgs>("view", "Cut a rectilinear photo with a known camera out of an HDR panorama", Developer,
                        kNoModels, add_view_options, run_view_command),
      command<SynthArgs>("synth", "Render a synthetic room or street with exact ground truth (test fixtures)",
                         Developer, kNoModels, add_synth_options, run_synth_command),
      command<RenderArgs>("render", "Render a SCENE.json (camera, OBJ meshes, lights) to an image", Developer,
                          kNoModels, add_render_options, run_render_command),
      command<BenchArgs>("bench", "Time and error of every stage, and the renderer's error-vs-time curve", Developer,
                         kInfers, add_bench_options, run_bench_command),
      command<RenderBenchArgs>(
          "bench render", "Renderer speed per size: rays/s vs a raw Embree loop, first snapshot, time to 1% error",
          Developer, kInfers, add_bench_render_options, run_bench_render_command),
      command<CameraBenchArgs>("bench camera", "The camera stage on real indoor lines with ground truth (NYU-VP)",
                               Developer, kInfers, add_bench_camera_options, run_bench_camera_command),
      command<GeometryBenchArgs>(
          "bench geometry", "Camera, depth and normals on generator scenes with ground truth, sweeping the knobs",
          Developer, kInfers, add_bench_geometry_options, run_bench_geometry_command),
      command<TransferBenchArgs>(
          "bench transfer", "Depth transfer alone on held-out rooms with the true camera: k and the warp", Developer,
          kInfers, add_bench_transfer_options, run_bench_transfer_command),
      command<SceneClassBenchArgs>("bench scene-class",
                                   "Indoor/outdoor: k-NN on the appearance descriptor vs the sky rule (renders, real "
                                   "panorama views leave-one-panorama-out, real photos)",
                                   Developer, kInfers, add_bench_scene_class_options, run_bench_scene_class_command),
      command<LightingBenchArgs>(
          "bench lighting", "Lights, intensities and camera response on generator scenes with exact lights", Developer,
          kInfers, add_bench_lighting_options, run_bench_lighting_command),
      command<WorldsBenchArgs>("bench worlds",
                               "Inference and composite on our own world, the Blender world and real panoramas",
                               Developer, kInfers, add_bench_worlds_options, run_bench_worlds_command),
      command<LightTrainingArgs>("bench lights",
                                 "The visible-light classifier against thresholding, each panorama and each fold of "
                                 "Blender photos held out",
                                 Developer, kInfers, add_bench_lights_options, run_bench_lights_command),
      command<IblTrainingArgs>(
          "bench ibl-ranking", "The IBL ranking function, leave one panorama out, against its single features",
          Developer, kInfers, add_bench_ibl_ranking_options, run_bench_ibl_ranking_command),
      command<CaptureBenchArgs>(
          "bench capture", "Frames per second and frame-to-client latency through propcamd on replayed frames",
          Developer, kInfers, add_bench_capture_options, run_bench_capture_command),
      command<LightTrainingArgs>("train-light-classifier",
                                 "Train the visible-light classifier on HDR panorama views and Blender-world photos "
                                 "(scripts/train_light_classifier.sh)",
                                 Developer, kNoModels, add_train_light_classifier_options,
                                 run_train_light_classifier_command),
      command<IblTrainingArgs>(
          "train-ibl-ranker", "Train the IBL ranking function on library views (scripts/train_ibl_ranker.sh)",
          Developer, kNoModels, add_train_ibl_ranker_options, run_train_ibl_ranker_command),
      command<DepthDatabaseArgs>(
          "build-depth-db", "Render the depth-transfer database from generator scenes (scripts/build_depth_db.sh)",
          Developer, kNoModels, add_build_depth_db_options, run_build_depth_db_command),
      command<SceneReferenceArgs>("build-scene-refs",
                                  "Build the scene-class references (and classifier): depth-database renders, real "
                                  "panorama views, Blender-world photos (scripts/build_scene_refs.sh)",
                                  Developer, kNoModels, add_build_scene_refs_options, run_build_scene_refs_command),
      command<IblLibraryArgs>(
          "build-ibl-library", "Build the annotated IBL panorama library (scripts/build_ibl_library.sh)", Developer,
          kNoModels, add_build_ibl_library_options, run_build_ibl_library_command),
  };
}

}  // namespace propcam::firmware
