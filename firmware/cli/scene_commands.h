// The renderer's and the fixtures' commands: `propcam props`, `synth`,
// `view`, `render` and `console`.
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>

#include "cli/cli_options.h"
#include "propcam/render/path_tracer.h"

namespace propcam::firmware {

struct PropsArgs {
  bool json_out = false;
  std::string thumbnails_dir;  // empty: list only
  std::string export_dir;      // empty: no export
  int thumbnail_size = 256, thumbnail_spp = 64;
};

void add_props_options(CLI::App& cmd, PropsArgs& args);
int run_props_command(const PropsArgs& args);

struct SynthArgs {
  std::string out, size = "640x480", prop;
  uint64_t seed = 1;
  int spp = 64;
  double height = 0;
  bool json_out = false;
  bool street = false;
};

void add_synth_options(CLI::App& cmd, SynthArgs& args);
int run_synth_command(const SynthArgs& args);

struct ViewArgs {
  std::string panorama, out, size = "640x480";
  double fov = 60, yaw = 0, pitch = 0, roll = 0, camera_height = 1.5;
  double exposure_ev = 0;
  bool json_out = false;
};

void add_view_options(CLI::App& cmd, ViewArgs& args);
int run_view_command(const ViewArgs& args);

struct RenderArgs {
  std::string scene, out;
  int spp = 16, bounces = kDefaultCliBounces, threads = 0;
  double time_budget = 0;  // seconds; 0: render `spp` samples in one pass
  double clamp = render::kDefaultMaxSampleLuminance;  // 0: off
  uint64_t seed = 0x5eed;
  bool json_out = false;
};

void add_render_options(CLI::App& cmd, RenderArgs& args);
int run_render_command(const RenderArgs& args);

struct ConsoleArgs {
  std::string tty = "/dev/tty0";
  bool restore = false;
};
void add_console_options(CLI::App& cmd, ConsoleArgs& args);
int run_console_command(const ConsoleArgs& args);

}  // namespace propcam::firmware
