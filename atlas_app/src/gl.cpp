#include "softatlas/app/gl.hpp"

namespace softatlas::app {

bool Gl::load(GlGetProc get, std::string& missing) {
#define SOFTATLAS_GL_LOAD(type, name)             \
  name = reinterpret_cast<type>(get("gl" #name)); \
  if (!name) {                                    \
    missing = "gl" #name;                         \
    return false;                                 \
  }
  SOFTATLAS_GL_FUNCTIONS(SOFTATLAS_GL_LOAD)
#undef SOFTATLAS_GL_LOAD
  return true;
}

}  // namespace softatlas::app
