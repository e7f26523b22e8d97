// Headless back end: OSMesa (Mesa's off-screen interface, llvmpipe rasteriser).
#include <GL/osmesa.h>

#include <stdexcept>

#include "softatlas/app/context.hpp"

namespace softatlas::app {
namespace {

class OsmesaContext final : public GlContext {
 public:
  OsmesaContext(int w, int h) : w_(w), h_(h), buffer_(static_cast<size_t>(w) * h * 4) {
    if (w <= 0 || h <= 0 || w > 16384 || h > 16384)
      throw std::runtime_error("headless context: width and height must be 1..16384");
    const int attribs[] = {OSMESA_FORMAT,
                           OSMESA_RGBA,
                           OSMESA_DEPTH_BITS,
                           24,
                           OSMESA_STENCIL_BITS,
                           0,
                           OSMESA_ACCUM_BITS,
                           0,
                           OSMESA_PROFILE,
                           OSMESA_CORE_PROFILE,
                           OSMESA_CONTEXT_MAJOR_VERSION,
                           3,
                           OSMESA_CONTEXT_MINOR_VERSION,
                           3,
                           0};
    ctx_ = OSMesaCreateContextAttribs(attribs, nullptr);
    if (!ctx_) throw std::runtime_error("OSMesa: cannot create an OpenGL 3.3 core context");
    if (!OSMesaMakeCurrent(ctx_, buffer_.data(), GL_UNSIGNED_BYTE, w, h))
      throw std::runtime_error("OSMesa: cannot make the context current");
    OSMesaPixelStore(OSMESA_Y_UP, 1);
    std::string missing;
    if (!gl_.load(reinterpret_cast<GlGetProc>(&OSMesaGetProcAddress), missing))
      throw std::runtime_error("OSMesa: missing OpenGL entry point " + missing);
  }
  ~OsmesaContext() override {
    if (ctx_) OSMesaDestroyContext(ctx_);
  }
  const char* backend() const override { return "osmesa"; }
  int width() const override { return w_; }
  int height() const override { return h_; }
  const Gl& gl() const override { return gl_; }
  bool headless() const override { return true; }

 private:
  int w_, h_;
  std::vector<uint8_t> buffer_;
  OSMesaContext ctx_ = nullptr;
  Gl gl_;
};

}  // namespace

std::unique_ptr<GlContext> make_osmesa_context(int width, int height) {
  return std::make_unique<OsmesaContext>(width, height);
}

std::string GlContext::describe() const {
  const auto* version = reinterpret_cast<const char*>(gl().GetString(GL_VERSION));
  const auto* renderer = reinterpret_cast<const char*>(gl().GetString(GL_RENDERER));
  return std::string(version ? version : "?") + " (" + (renderer ? renderer : "?") + ")";
}

std::vector<uint8_t> GlContext::read_rgba() const {
  const int w = width(), h = height();
  std::vector<uint8_t> rows(static_cast<size_t>(w) * h * 4), out(rows.size());
  gl().PixelStorei(GL_PACK_ALIGNMENT, 1);
  gl().Finish();
  gl().ReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, rows.data());
  // GL's origin is the bottom row; images start at the top.
  const size_t stride = static_cast<size_t>(w) * 4;
  for (int y = 0; y < h; ++y)
    std::copy(rows.begin() + static_cast<long>((h - 1 - y) * stride),
              rows.begin() + static_cast<long>((h - y) * stride), out.begin() + static_cast<long>(y * stride));
  return out;
}

}  // namespace softatlas::app
