// Render and haptic benchmarks (`softatlas bench render|haptic`).
#pragma once

#include <string>

namespace softatlas::app {

struct RenderBenchOptions {
  std::string set;
  int width = 1280, height = 720, frames = 300;
  bool deform = true;  // upload new positions + normals every frame, as a live simulation does
  bool ui = true;      // draw labels and the caption through Dear ImGui
};
// Returns the JSON text (fps, ms_per_frame, faces, ...).
std::string bench_render(const RenderBenchOptions& options);

struct HapticBenchOptions {
  std::string set;
  double seconds = 10.0;
  int width = 640, height = 360;
  bool realtime = true;
  int render_threads = 1;  // LP_NUM_THREADS for llvmpipe unless already set
  double amplitude_mm = 10.0;
  // Render pacing: a window shows frames at the display rate (GLFW swap interval 1), so the
  // render loop beside the haptic loop is paced to this rate; 0 renders as fast as it can.
  double render_fps = 60.0;
};
std::string bench_haptic(const HapticBenchOptions& options);

}  // namespace softatlas::app
