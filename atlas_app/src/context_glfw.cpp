// Window back end: GLFW. GLFW loads libGL itself (dlopen), so gl* symbols of libGL never meet
// those of libOSMesa in the global namespace; the renderer calls through the Gl table.
#include <GLFW/glfw3.h>

#include <stdexcept>

#include "softatlas/app/context.hpp"

namespace softatlas::app {
namespace {

class GlfwContext final : public GlContext {
 public:
  GlfwContext(int w, int h, const std::string& title) {
    if (!glfwInit()) throw std::runtime_error("GLFW: cannot initialise (no display? use --headless)");
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_SAMPLES, 4);
    window_ = glfwCreateWindow(w, h, title.c_str(), nullptr, nullptr);
    if (!window_) {
      glfwTerminate();
      throw std::runtime_error("GLFW: cannot open an OpenGL 3.3 core window (use --headless)");
    }
    glfwMakeContextCurrent(window_);
    glfwSwapInterval(1);
    std::string missing;
    if (!gl_.load(reinterpret_cast<GlGetProc>(&glfwGetProcAddress), missing))
      throw std::runtime_error("GLFW: missing OpenGL entry point " + missing);
  }
  ~GlfwContext() override {
    if (window_) glfwDestroyWindow(window_);
    glfwTerminate();
  }
  const char* backend() const override { return "glfw"; }
  int width() const override {
    int w, h;
    glfwGetFramebufferSize(window_, &w, &h);
    return w;
  }
  int height() const override {
    int w, h;
    glfwGetFramebufferSize(window_, &w, &h);
    return h;
  }
  const Gl& gl() const override { return gl_; }
  bool headless() const override { return false; }
  void swap() override { glfwSwapBuffers(window_); }
  bool should_close() const override { return glfwWindowShouldClose(window_); }
  void poll_events() override { glfwPollEvents(); }
  GLFWwindow* window() override { return window_; }

 private:
  GLFWwindow* window_ = nullptr;
  Gl gl_;
};

}  // namespace

std::unique_ptr<GlContext> make_glfw_context(int width, int height, const std::string& title) {
  return std::make_unique<GlfwContext>(width, height, title);
}

}  // namespace softatlas::app
