// OpenGL 3.3 core entry points, loaded at run time through a get-proc-address callback.
//
// Why a table and not direct calls: the headless back end (libOSMesa) and the window back end
// (libGL via GLFW) both export gl* symbols. Calling gl* directly would bind every call to
// whichever library the dynamic linker saw first. The renderer instead calls through this table,
// filled from OSMesaGetProcAddress or glfwGetProcAddress, so one binary links libOSMesa and
// libglfw (GLFW dlopens libGL with RTLD_LOCAL) and each context gets its own entry points.
#pragma once

#include <GL/glcorearb.h>

#include <string>

namespace softatlas::app {

using GlProc = void (*)();
using GlGetProc = GlProc (*)(const char* name);

// GL 1.0/1.1 entry points get their own pointer types: GL/gl.h (pulled in by osmesa.h) hides
// glcorearb.h's typedefs for them.
typedef const GLubyte*(APIENTRYP SaGlGetStringFn)(GLenum name);
typedef GLenum(APIENTRYP SaGlGetErrorFn)(void);
typedef void(APIENTRYP SaGlClearFn)(GLbitfield mask);
typedef void(APIENTRYP SaGlClearColorFn)(GLfloat r, GLfloat g, GLfloat b, GLfloat a);
typedef void(APIENTRYP SaGlViewportFn)(GLint x, GLint y, GLsizei w, GLsizei h);
typedef void(APIENTRYP SaGlEnableFn)(GLenum cap);
typedef void(APIENTRYP SaGlDisableFn)(GLenum cap);
typedef void(APIENTRYP SaGlBlendFuncFn)(GLenum s, GLenum d);
typedef void(APIENTRYP SaGlDepthMaskFn)(GLboolean flag);
typedef void(APIENTRYP SaGlDepthFuncFn)(GLenum func);
typedef void(APIENTRYP SaGlCullFaceFn)(GLenum mode);
typedef void(APIENTRYP SaGlFrontFaceFn)(GLenum mode);
typedef void(APIENTRYP SaGlScissorFn)(GLint x, GLint y, GLsizei w, GLsizei h);
typedef void(APIENTRYP SaGlReadPixelsFn)(GLint x, GLint y, GLsizei w, GLsizei h, GLenum format, GLenum type,
                                         void* pixels);
typedef void(APIENTRYP SaGlPixelStoreiFn)(GLenum pname, GLint param);
typedef void(APIENTRYP SaGlFinishFn)(void);
typedef void(APIENTRYP SaGlLineWidthFn)(GLfloat width);
typedef void(APIENTRYP SaGlDrawElementsFn)(GLenum mode, GLsizei count, GLenum type, const void* indices);
typedef void(APIENTRYP SaGlDrawArraysFn)(GLenum mode, GLint first, GLsizei count);
typedef void(APIENTRYP SaGlGenTexturesFn)(GLsizei n, GLuint* textures);
typedef void(APIENTRYP SaGlDeleteTexturesFn)(GLsizei n, const GLuint* textures);
typedef void(APIENTRYP SaGlBindTextureFn)(GLenum target, GLuint texture);
typedef void(APIENTRYP SaGlTexImage2DFn)(GLenum target, GLint level, GLint internalformat, GLsizei w, GLsizei h,
                                         GLint border, GLenum format, GLenum type, const void* pixels);
typedef void(APIENTRYP SaGlTexParameteriFn)(GLenum target, GLenum pname, GLint param);
typedef void(APIENTRYP SaGlColorMaskFn)(GLboolean r, GLboolean g, GLboolean b, GLboolean a);

#define SOFTATLAS_GL_FUNCTIONS(X)                              \
  X(SaGlGetStringFn, GetString)                                \
  X(SaGlGetErrorFn, GetError)                                  \
  X(SaGlClearFn, Clear)                                        \
  X(SaGlClearColorFn, ClearColor)                              \
  X(SaGlViewportFn, Viewport)                                  \
  X(SaGlEnableFn, Enable)                                      \
  X(SaGlDisableFn, Disable)                                    \
  X(SaGlBlendFuncFn, BlendFunc)                                \
  X(PFNGLBLENDFUNCSEPARATEPROC, BlendFuncSeparate)             \
  X(PFNGLBLENDEQUATIONPROC, BlendEquation)                     \
  X(SaGlDepthMaskFn, DepthMask)                                \
  X(SaGlDepthFuncFn, DepthFunc)                                \
  X(SaGlCullFaceFn, CullFace)                                  \
  X(SaGlFrontFaceFn, FrontFace)                                \
  X(SaGlScissorFn, Scissor)                                    \
  X(SaGlReadPixelsFn, ReadPixels)                              \
  X(SaGlPixelStoreiFn, PixelStorei)                            \
  X(SaGlFinishFn, Finish)                                      \
  X(SaGlLineWidthFn, LineWidth)                                \
  X(PFNGLGENBUFFERSPROC, GenBuffers)                           \
  X(PFNGLDELETEBUFFERSPROC, DeleteBuffers)                     \
  X(PFNGLBINDBUFFERPROC, BindBuffer)                           \
  X(PFNGLBUFFERDATAPROC, BufferData)                           \
  X(PFNGLBUFFERSUBDATAPROC, BufferSubData)                     \
  X(PFNGLGENVERTEXARRAYSPROC, GenVertexArrays)                 \
  X(PFNGLDELETEVERTEXARRAYSPROC, DeleteVertexArrays)           \
  X(PFNGLBINDVERTEXARRAYPROC, BindVertexArray)                 \
  X(PFNGLVERTEXATTRIBPOINTERPROC, VertexAttribPointer)         \
  X(PFNGLENABLEVERTEXATTRIBARRAYPROC, EnableVertexAttribArray) \
  X(PFNGLCREATESHADERPROC, CreateShader)                       \
  X(PFNGLSHADERSOURCEPROC, ShaderSource)                       \
  X(PFNGLCOMPILESHADERPROC, CompileShader)                     \
  X(PFNGLGETSHADERIVPROC, GetShaderiv)                         \
  X(PFNGLGETSHADERINFOLOGPROC, GetShaderInfoLog)               \
  X(PFNGLDELETESHADERPROC, DeleteShader)                       \
  X(PFNGLCREATEPROGRAMPROC, CreateProgram)                     \
  X(PFNGLATTACHSHADERPROC, AttachShader)                       \
  X(PFNGLLINKPROGRAMPROC, LinkProgram)                         \
  X(PFNGLGETPROGRAMIVPROC, GetProgramiv)                       \
  X(PFNGLGETPROGRAMINFOLOGPROC, GetProgramInfoLog)             \
  X(PFNGLUSEPROGRAMPROC, UseProgram)                           \
  X(PFNGLDELETEPROGRAMPROC, DeleteProgram)                     \
  X(PFNGLGETUNIFORMLOCATIONPROC, GetUniformLocation)           \
  X(PFNGLUNIFORM1IPROC, Uniform1i)                             \
  X(PFNGLUNIFORM1FPROC, Uniform1f)                             \
  X(PFNGLUNIFORM3FPROC, Uniform3f)                             \
  X(PFNGLUNIFORM4FPROC, Uniform4f)                             \
  X(PFNGLUNIFORMMATRIX4FVPROC, UniformMatrix4fv)               \
  X(SaGlDrawElementsFn, DrawElements)                          \
  X(SaGlDrawArraysFn, DrawArrays)                              \
  X(SaGlGenTexturesFn, GenTextures)                            \
  X(SaGlDeleteTexturesFn, DeleteTextures)                      \
  X(SaGlBindTextureFn, BindTexture)                            \
  X(PFNGLACTIVETEXTUREPROC, ActiveTexture)                     \
  X(SaGlTexImage2DFn, TexImage2D)                              \
  X(SaGlColorMaskFn, ColorMask)                                \
  X(SaGlTexParameteriFn, TexParameteri)

struct Gl {
#define SOFTATLAS_GL_MEMBER(type, name) type name = nullptr;
  SOFTATLAS_GL_FUNCTIONS(SOFTATLAS_GL_MEMBER)
#undef SOFTATLAS_GL_MEMBER

  // Fills every entry through `get` ("gl" + name). Returns false and names the first missing
  // entry point in `missing` if the context lacks one.
  bool load(GlGetProc get, std::string& missing);
};

}  // namespace softatlas::app
