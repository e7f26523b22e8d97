// GL contexts: one interface, two back ends (polyscope keeps a mock back end for tests; ours is
// a real headless one). Both give an OpenGL 3.3+ core context and a get-proc-address callback
// for the Gl table (gl.hpp explains why no gl* symbol is called directly).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "softatlas/app/gl.hpp"

struct GLFWwindow;

namespace softatlas::app {

class GlContext {
 public:
  virtual ~GlContext() = default;
  virtual const char* backend() const = 0;  // "osmesa" | "glfw"
  virtual int width() const = 0;            // framebuffer size in pixels
  virtual int height() const = 0;
  virtual const Gl& gl() const = 0;
  virtual bool headless() const = 0;
  virtual void swap() {}  // present (window back end)
  virtual bool should_close() const { return false; }
  virtual void poll_events() {}
  virtual GLFWwindow* window() { return nullptr; }
  // GL_VERSION and GL_RENDERER of the context.
  std::string describe() const;
  // RGBA8 pixels of the current framebuffer, top row first (#W*H*4).
  std::vector<uint8_t> read_rgba() const;
};

// Headless OSMesa context of size w x h (OpenGL core >= 3.3). Throws std::runtime_error if OSMesa
// cannot give a core 3.3 context. llvmpipe spawns LP_NUM_THREADS render threads (default: one
// per core); callers that share the machine with a real-time loop set it before this call.
std::unique_ptr<GlContext> make_osmesa_context(int width, int height);

// A GLFW window with an OpenGL 3.3 core context. Throws std::runtime_error without a display.
std::unique_ptr<GlContext> make_glfw_context(int width, int height, const std::string& title);

}  // namespace softatlas::app
