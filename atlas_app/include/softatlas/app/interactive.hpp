// The interactive viewer (GLFW window): physics on its own thread, the mouse as a virtual
// haptic device on the 1 kHz loop, Dear ImGui panel (organs, physics, lesson, stats).
#pragma once

#include <string>

#include "softatlas/app/lesson.hpp"

namespace softatlas::app {

struct WindowOptions {
  int width = 1280, height = 800;
  bool realtime = true;
  double max_force_N = 4.0;
  int frames = 0;          // > 0: close after this many frames (scripts, Xvfb checks)
  std::string screenshot;  // written after the last frame when frames > 0
  std::string slice;       // --slice PLANE:MM as given ("" = none)
  SlicePlane slice_plane;  // parsed from it
};

// Runs until the window closes. `lesson` may be null (plain organ-set view).
int run_window(const io::OrganSet& set, const Lesson* lesson, const WindowOptions& options);

}  // namespace softatlas::app
