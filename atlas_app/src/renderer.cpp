#include "softatlas/app/renderer.hpp"

#include <imgui.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace softatlas::app {
namespace {

const char* kOrganVs = R"(#version 330 core
layout(location = 0) in vec3 in_pos;
layout(location = 1) in vec3 in_normal;
uniform mat4 u_view;
uniform mat4 u_proj;
out vec3 v_normal;
out vec3 v_pos;
out vec3 v_world;
void main() {
  vec4 p = u_view * vec4(in_pos, 1.0);
  v_pos = p.xyz;
  v_world = in_pos;
  v_normal = mat3(u_view) * in_normal;
  gl_Position = u_proj * p;
})";

// Headlight Blinn-Phong; highlight adds a rim (Fresnel-like) glow so the organ stands out
// without hiding its shading. A slice plane (u_clip: n.x + d > 0 is cut away) removes the near
// half; the inside (back faces, seen through the cut) is drawn flat and darker: the section.
const char* kOrganFs = R"(#version 330 core
in vec3 v_normal;
in vec3 v_pos;
in vec3 v_world;
uniform vec4 u_color;
uniform float u_highlight;
uniform vec4 u_clip;
uniform int u_ct;
out vec4 frag;
void main() {
  if (dot(u_clip.xyz, v_world) + u_clip.w > 0.0) discard;
  // With the CT on the plane, alpha marks what the CT quad shows: 0 = CT only (front faces are
  // behind the plane), 0.45 = the section, the organ's colour over the CT.
  if (!gl_FrontFacing) { frag = u_ct == 1 ? vec4(u_color.rgb, 0.45) : vec4(u_color.rgb * 0.55, u_color.a); return; }
  vec3 n = normalize(v_normal);
  vec3 v = normalize(-v_pos);
  vec3 l = normalize(vec3(0.3, 0.5, 1.0));
  float diff = max(dot(n, l), 0.0);
  vec3 h = normalize(l + v);
  float spec = pow(max(dot(n, h), 0.0), 40.0) * 0.25;
  vec3 c = u_color.rgb * (0.28 + 0.72 * diff) + vec3(spec);
  float rim = pow(1.0 - max(dot(n, v), 0.0), 2.0);
  c = mix(c, vec3(1.0, 0.95, 0.35), u_highlight * (0.12 + 0.6 * rim));
  frag = vec4(c, u_ct == 1 ? 0.0 : u_color.a);
})";

// The CT on the slice plane: window grey levels in the texture; texels outside the CT discarded.
const char* kCtVs = R"(#version 330 core
layout(location = 0) in vec3 in_pos;
layout(location = 1) in vec2 in_uv;
uniform mat4 u_mvp;
out vec2 v_uv;
void main() { v_uv = in_uv; gl_Position = u_mvp * vec4(in_pos, 1.0); })";
const char* kCtFs = R"(#version 330 core
in vec2 v_uv;
uniform sampler2D u_tex;
out vec4 frag;
void main() {
  vec4 t = texture(u_tex, v_uv);
  if (t.a < 0.5) discard;
  frag = vec4(t.rgb, 1.0);
})";

const char* kLineVs = R"(#version 330 core
layout(location = 0) in vec3 in_pos;
layout(location = 1) in vec4 in_color;
uniform mat4 u_mvp;
out vec4 v_color;
void main() { v_color = in_color; gl_Position = u_mvp * vec4(in_pos, 1.0); })";
const char* kLineFs = R"(#version 330 core
in vec4 v_color;
out vec4 frag;
void main() { frag = v_color; })";

const char* kImguiVs = R"(#version 330 core
layout(location = 0) in vec2 in_pos;
layout(location = 1) in vec2 in_uv;
layout(location = 2) in vec4 in_color;
uniform mat4 u_proj;
out vec2 v_uv;
out vec4 v_color;
void main() { v_uv = in_uv; v_color = in_color; gl_Position = u_proj * vec4(in_pos, 0.0, 1.0); })";
const char* kImguiFs = R"(#version 330 core
in vec2 v_uv;
in vec4 v_color;
uniform sampler2D u_tex;
out vec4 frag;
void main() { frag = v_color * texture(u_tex, v_uv); })";

uint32_t compile_program(const Gl& gl, const char* vs, const char* fs, const char* what) {
  auto shader = [&](GLenum kind, const char* src) {
    GLuint s = gl.CreateShader(kind);
    gl.ShaderSource(s, 1, &src, nullptr);
    gl.CompileShader(s);
    GLint ok = 0;
    gl.GetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
      char log[2048];
      gl.GetShaderInfoLog(s, sizeof log, nullptr, log);
      throw std::runtime_error(std::string("renderer: ") + what + " shader: " + log);
    }
    return s;
  };
  GLuint v = shader(GL_VERTEX_SHADER, vs), f = shader(GL_FRAGMENT_SHADER, fs);
  GLuint p = gl.CreateProgram();
  gl.AttachShader(p, v);
  gl.AttachShader(p, f);
  gl.LinkProgram(p);
  gl.DeleteShader(v);
  gl.DeleteShader(f);
  GLint ok = 0;
  gl.GetProgramiv(p, GL_LINK_STATUS, &ok);
  if (!ok) {
    char log[2048];
    gl.GetProgramInfoLog(p, sizeof log, nullptr, log);
    throw std::runtime_error(std::string("renderer: ") + what + " program: " + log);
  }
  return p;
}

}  // namespace

Renderer::Renderer(const GlContext& context) : gl_(context.gl()) {
  organ_program_ = compile_program(gl_, kOrganVs, kOrganFs, "organ");
  line_program_ = compile_program(gl_, kLineVs, kLineFs, "line");
  imgui_program_ = compile_program(gl_, kImguiVs, kImguiFs, "imgui");
  ct_program_ = compile_program(gl_, kCtVs, kCtFs, "ct slice");
  gl_.GenVertexArrays(1, &ct_vao_);
  gl_.GenBuffers(1, &ct_vbo_);
  gl_.BindVertexArray(ct_vao_);
  gl_.BindBuffer(GL_ARRAY_BUFFER, ct_vbo_);
  gl_.BufferData(GL_ARRAY_BUFFER, 6 * 5 * sizeof(float), nullptr, GL_DYNAMIC_DRAW);
  gl_.EnableVertexAttribArray(0);
  gl_.VertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 5 * sizeof(float), nullptr);
  gl_.EnableVertexAttribArray(1);
  gl_.VertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, 5 * sizeof(float), reinterpret_cast<void*>(3 * sizeof(float)));
  gl_.GenVertexArrays(1, &line_vao_);
  gl_.GenBuffers(1, &line_vbo_);
  gl_.BindVertexArray(line_vao_);
  gl_.BindBuffer(GL_ARRAY_BUFFER, line_vbo_);
  gl_.EnableVertexAttribArray(0);
  gl_.VertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 7 * sizeof(float), nullptr);
  gl_.EnableVertexAttribArray(1);
  gl_.VertexAttribPointer(1, 4, GL_FLOAT, GL_FALSE, 7 * sizeof(float), reinterpret_cast<void*>(3 * sizeof(float)));
  gl_.GenVertexArrays(1, &imgui_vao_);
  gl_.GenBuffers(1, &imgui_vbo_);
  gl_.GenBuffers(1, &imgui_ebo_);
  gl_.BindVertexArray(imgui_vao_);
  gl_.BindBuffer(GL_ARRAY_BUFFER, imgui_vbo_);
  gl_.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, imgui_ebo_);
  gl_.EnableVertexAttribArray(0);
  gl_.VertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, sizeof(ImDrawVert),
                          reinterpret_cast<void*>(IM_OFFSETOF(ImDrawVert, pos)));
  gl_.EnableVertexAttribArray(1);
  gl_.VertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, sizeof(ImDrawVert),
                          reinterpret_cast<void*>(IM_OFFSETOF(ImDrawVert, uv)));
  gl_.EnableVertexAttribArray(2);
  gl_.VertexAttribPointer(2, 4, GL_UNSIGNED_BYTE, GL_TRUE, sizeof(ImDrawVert),
                          reinterpret_cast<void*>(IM_OFFSETOF(ImDrawVert, col)));
  gl_.BindVertexArray(0);
}

Renderer::~Renderer() {
  for (Mesh& m : meshes_) {
    gl_.DeleteBuffers(1, &m.vbo);
    gl_.DeleteBuffers(1, &m.ebo);
    gl_.DeleteVertexArrays(1, &m.vao);
  }
  gl_.DeleteBuffers(1, &line_vbo_);
  gl_.DeleteVertexArrays(1, &line_vao_);
  gl_.DeleteBuffers(1, &imgui_vbo_);
  gl_.DeleteBuffers(1, &imgui_ebo_);
  gl_.DeleteVertexArrays(1, &imgui_vao_);
  if (font_texture_) gl_.DeleteTextures(1, &font_texture_);
  if (ct_texture_) gl_.DeleteTextures(1, &ct_texture_);
  gl_.DeleteBuffers(1, &ct_vbo_);
  gl_.DeleteVertexArrays(1, &ct_vao_);
  gl_.DeleteProgram(ct_program_);
  gl_.DeleteProgram(organ_program_);
  gl_.DeleteProgram(line_program_);
  gl_.DeleteProgram(imgui_program_);
}

int Renderer::add_mesh(const std::vector<int32_t>& faces, size_t nvert) {
  Mesh m;
  m.faces = faces;
  m.nvert = nvert;
  m.interleaved.assign(nvert * 6, 0.0f);
  gl_.GenVertexArrays(1, &m.vao);
  gl_.GenBuffers(1, &m.vbo);
  gl_.GenBuffers(1, &m.ebo);
  gl_.BindVertexArray(m.vao);
  gl_.BindBuffer(GL_ARRAY_BUFFER, m.vbo);
  gl_.BufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(m.interleaved.size() * sizeof(float)), nullptr,
                 GL_DYNAMIC_DRAW);
  gl_.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, m.ebo);
  std::vector<uint32_t> idx(faces.begin(), faces.end());
  gl_.BufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(idx.size() * sizeof(uint32_t)), idx.data(),
                 GL_STATIC_DRAW);
  gl_.EnableVertexAttribArray(0);
  gl_.VertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float), nullptr);
  gl_.EnableVertexAttribArray(1);
  gl_.VertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float), reinterpret_cast<void*>(3 * sizeof(float)));
  gl_.BindVertexArray(0);
  meshes_.push_back(std::move(m));
  return static_cast<int>(meshes_.size()) - 1;
}

size_t Renderer::face_count() const {
  size_t n = 0;
  for (const Mesh& m : meshes_) n += m.faces.size() / 3;
  return n;
}

void Renderer::set_positions(int mesh, const double* xyz) {
  Mesh& m = meshes_.at(static_cast<size_t>(mesh));
  for (size_t i = 0; i < m.nvert; ++i)
    for (int k = 0; k < 3; ++k) m.interleaved[6 * i + k] = static_cast<float>(xyz[3 * i + k]);
  upload(m);
}

void Renderer::set_positions(int mesh, const float* xyz) {
  Mesh& m = meshes_.at(static_cast<size_t>(mesh));
  for (size_t i = 0; i < m.nvert; ++i)
    for (int k = 0; k < 3; ++k) m.interleaved[6 * i + k] = xyz[3 * i + k];
  upload(m);
}

void Renderer::upload(Mesh& m) {
  // Smooth-shading normals: sum of unnormalised face normals (area weighted), then normalised.
  float* v = m.interleaved.data();
  for (size_t i = 0; i < m.nvert; ++i) v[6 * i + 3] = v[6 * i + 4] = v[6 * i + 5] = 0.0f;
  const size_t nf = m.faces.size() / 3;
  for (size_t f = 0; f < nf; ++f) {
    const int32_t a = m.faces[3 * f], b = m.faces[3 * f + 1], c = m.faces[3 * f + 2];
    const float e1[3] = {v[6 * b] - v[6 * a], v[6 * b + 1] - v[6 * a + 1], v[6 * b + 2] - v[6 * a + 2]};
    const float e2[3] = {v[6 * c] - v[6 * a], v[6 * c + 1] - v[6 * a + 1], v[6 * c + 2] - v[6 * a + 2]};
    const float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    for (int32_t idx : {a, b, c})
      for (int k = 0; k < 3; ++k) v[6 * idx + 3 + k] += n[k];
  }
  Eigen::Vector3f sum(0, 0, 0);
  for (size_t i = 0; i < m.nvert; ++i) {
    float* n = v + 6 * i + 3;
    const float len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (len > 0)
      for (int k = 0; k < 3; ++k) n[k] /= len;
    sum += Eigen::Vector3f(v[6 * i], v[6 * i + 1], v[6 * i + 2]);
  }
  if (m.nvert) m.centroid = sum / static_cast<float>(m.nvert);
  gl_.BindBuffer(GL_ARRAY_BUFFER, m.vbo);
  gl_.BufferSubData(GL_ARRAY_BUFFER, 0, static_cast<GLsizeiptr>(m.interleaved.size() * sizeof(float)),
                    m.interleaved.data());
}

void Renderer::set_bounds(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi) {
  lo_ = lo;
  hi_ = hi;
}

void Renderer::begin_frame(const Cues& cues, int width, int height) {
  width_ = width;
  height_ = height;
  gl_.Viewport(0, 0, width, height);
  // Alpha 0 under the CT plane: the CT quad shows where alpha is 0 (see kOrganFs).
  gl_.ClearColor(cues.background[0], cues.background[1], cues.background[2], ct_on_plane() ? 0.0f : 1.0f);
  gl_.DepthMask(GL_TRUE);
  gl_.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
}

void Renderer::draw_organs(const Camera& camera, const std::vector<OrganStyle>& styles) {
  const Eigen::Matrix4f view = camera.view(), proj = camera.projection();
  gl_.UseProgram(organ_program_);
  gl_.UniformMatrix4fv(gl_.GetUniformLocation(organ_program_, "u_view"), 1, GL_FALSE, view.data());
  gl_.UniformMatrix4fv(gl_.GetUniformLocation(organ_program_, "u_proj"), 1, GL_FALSE, proj.data());
  const GLint u_color = gl_.GetUniformLocation(organ_program_, "u_color");
  const GLint u_highlight = gl_.GetUniformLocation(organ_program_, "u_highlight");
  const Eigen::Vector4f clip = slice_.clip();
  gl_.Uniform4f(gl_.GetUniformLocation(organ_program_, "u_clip"), clip[0], clip[1], clip[2], clip[3]);
  gl_.Uniform1i(gl_.GetUniformLocation(organ_program_, "u_ct"), ct_on_plane() ? 1 : 0);
  gl_.Enable(GL_DEPTH_TEST);
  gl_.DepthFunc(GL_LESS);
  if (slice_.active())
    gl_.Disable(GL_CULL_FACE);  // the cut shows the inside
  else
    gl_.Enable(GL_CULL_FACE);
  gl_.CullFace(GL_BACK);
  gl_.FrontFace(GL_CCW);
  auto draw = [&](size_t i) {
    const OrganStyle& s = styles[i];
    gl_.Uniform4f(u_color, s.color[0], s.color[1], s.color[2], s.alpha);
    gl_.Uniform1f(u_highlight, s.highlight ? 1.0f : 0.0f);
    gl_.BindVertexArray(meshes_[i].vao);
    gl_.DrawElements(GL_TRIANGLES, static_cast<GLsizei>(meshes_[i].faces.size()), GL_UNSIGNED_INT, nullptr);
  };
  const size_t n = std::min(styles.size(), meshes_.size());
  gl_.Disable(GL_BLEND);
  for (size_t i = 0; i < n; ++i)
    if (styles[i].visible && styles[i].alpha >= 1.0f) draw(i);
  // Context organs: back to front by centroid, blended, without writing depth.
  std::vector<size_t> transparent;
  for (size_t i = 0; i < n; ++i)
    if (styles[i].visible && styles[i].alpha < 1.0f) transparent.push_back(i);
  const Eigen::Vector3f eye = camera.eye();
  std::sort(transparent.begin(), transparent.end(), [&](size_t a, size_t b) {
    return (meshes_[a].centroid - eye).squaredNorm() > (meshes_[b].centroid - eye).squaredNorm();
  });
  if (!transparent.empty()) {
    gl_.Enable(GL_BLEND);
    gl_.BlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ZERO, GL_ONE);  // alpha kept
    gl_.DepthMask(GL_FALSE);
    for (size_t i : transparent) draw(i);
    gl_.DepthMask(GL_TRUE);
    gl_.Disable(GL_BLEND);
  }
  gl_.BindVertexArray(0);
}

void Renderer::draw_lines(const Camera& camera, const std::vector<Line>& lines) {
  if (lines.empty()) return;
  std::vector<float> data;
  data.reserve(lines.size() * 14);
  for (const Line& l : lines)
    for (const Eigen::Vector3f& p : {l.a, l.b})
      data.insert(data.end(), {p.x(), p.y(), p.z(), l.color[0], l.color[1], l.color[2], l.color[3]});
  const Eigen::Matrix4f mvp = camera.projection() * camera.view();
  gl_.UseProgram(line_program_);
  gl_.UniformMatrix4fv(gl_.GetUniformLocation(line_program_, "u_mvp"), 1, GL_FALSE, mvp.data());
  gl_.BindVertexArray(line_vao_);
  gl_.BindBuffer(GL_ARRAY_BUFFER, line_vbo_);
  gl_.BufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(data.size() * sizeof(float)), data.data(), GL_STREAM_DRAW);
  gl_.Enable(GL_BLEND);
  gl_.BlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ZERO, GL_ONE);  // alpha kept
  gl_.DrawArrays(GL_LINES, 0, static_cast<GLsizei>(lines.size() * 2));
  gl_.Disable(GL_BLEND);
  gl_.BindVertexArray(0);
}

void Renderer::draw_cues(const Camera& camera, const Cues& cues) {
  std::vector<Line> lines;
  const Eigen::Vector3f size = hi_ - lo_;
  const float step = 20.0f;  // mm: a 2 cm grid gives scale at a glance
  if (cues.grid) {
    // Grid on the posterior body wall (the plane behind the organs, where they are anchored).
    const float y = lo_.y() - 0.1f * size.y();
    const float x0 = std::floor((lo_.x() - 0.2f * size.x()) / step) * step;
    const float x1 = std::ceil((hi_.x() + 0.2f * size.x()) / step) * step;
    const float z0 = std::floor((lo_.z() - 0.2f * size.z()) / step) * step;
    const float z1 = std::ceil((hi_.z() + 0.2f * size.z()) / step) * step;
    const std::array<float, 4> c{0.45f, 0.48f, 0.52f, 0.35f};
    for (float x = x0; x <= x1 + 0.1f; x += step) lines.push_back({{x, y, z0}, {x, y, z1}, c});
    for (float z = z0; z <= z1 + 0.1f; z += step) lines.push_back({{x0, y, z}, {x1, y, z}, c});
  }
  if (cues.axes) {
    // R (red), A (green), S (blue) from the scene's lower posterior corner.
    const Eigen::Vector3f o(lo_.x() - 0.1f * size.x(), lo_.y() - 0.1f * size.y(), lo_.z() - 0.1f * size.z());
    const float len = 0.25f * size.maxCoeff();
    lines.push_back({o, o + Eigen::Vector3f(len, 0, 0), {0.95f, 0.3f, 0.3f, 1.0f}});
    lines.push_back({o, o + Eigen::Vector3f(0, len, 0), {0.3f, 0.9f, 0.3f, 1.0f}});
    lines.push_back({o, o + Eigen::Vector3f(0, 0, len), {0.35f, 0.5f, 1.0f, 1.0f}});
  }
  gl_.Enable(GL_DEPTH_TEST);
  draw_lines(camera, lines);
}

void add_arrow(std::vector<Line>& lines, const Eigen::Vector3f& a, const Eigen::Vector3f& b,
               const std::array<float, 4>& color) {
  const Eigen::Vector3f d = b - a;
  const float len = d.norm();
  if (len <= 0) return;
  const Eigen::Vector3f u = d / len;
  const Eigen::Vector3f p =
      u.cross(std::abs(u.x()) < 0.9f ? Eigen::Vector3f::UnitX() : Eigen::Vector3f::UnitY()).normalized();
  const Eigen::Vector3f q = u.cross(p);
  // GL core lines are one pixel wide: a bundle of shafts 0.4 mm apart reads as a thick arrow.
  for (const Eigen::Vector3f& o : {Eigen::Vector3f::Zero().eval(), Eigen::Vector3f(0.4f * p),
                                   Eigen::Vector3f(-0.4f * p), Eigen::Vector3f(0.4f * q), Eigen::Vector3f(-0.4f * q)})
    lines.push_back({a + o, b + o, color});
  const float h = std::min(0.3f * len, 8.0f);
  for (const Eigen::Vector3f& side : {p, q, Eigen::Vector3f(-p), Eigen::Vector3f(-q)})
    lines.push_back({b, b - h * u + 0.45f * h * side, color});
}

Eigen::Vector4f SlicePlane::clip() const {
  if (!active()) return {0, 0, 0, -1};  // never > 0: nothing cut
  Eigen::Vector4f c(0, 0, 0, 0);
  c[axis] = keep_below ? 1.0f : -1.0f;
  c[3] = keep_below ? -at_mm : at_mm;
  return c;
}

void Renderer::set_depth_test(bool on) {
  if (on)
    gl_.Enable(GL_DEPTH_TEST);
  else
    gl_.Disable(GL_DEPTH_TEST);
}

void Renderer::draw_slice(const Camera& camera, const SlicePlane& plane) {
  if (!plane.active()) return;
  // The plane over the scene's bounds (+10%): a translucent sheet and its outline.
  const Eigen::Vector3f size = hi_ - lo_;
  const Eigen::Vector3f lo = lo_ - 0.1f * size, hi = hi_ + 0.1f * size;
  const int a = plane.axis, u = (a + 1) % 3, v = (a + 2) % 3;
  Eigen::Vector3f corner[4];
  for (int k = 0; k < 4; ++k) {
    corner[k][a] = plane.at_mm;
    corner[k][u] = (k == 1 || k == 2) ? hi[u] : lo[u];
    corner[k][v] = (k >= 2) ? hi[v] : lo[v];
  }
  std::vector<Line> lines;
  const std::array<float, 4> edge{0.55f, 0.85f, 1.0f, 0.9f}, hatch{0.55f, 0.85f, 1.0f, 0.10f};
  for (int k = 0; k < 4; ++k) lines.push_back({corner[k], corner[(k + 1) % 4], edge});
  const int n = ct_on_plane() ? 0 : 16;  // hatching: reads as a sheet, without a blended fill
  for (int k = 1; k < n; ++k) {
    const float t = static_cast<float>(k) / n;
    lines.push_back({corner[0] + t * (corner[1] - corner[0]), corner[3] + t * (corner[2] - corner[3]), hatch});
    lines.push_back({corner[0] + t * (corner[3] - corner[0]), corner[1] + t * (corner[2] - corner[1]), hatch});
  }
  gl_.Enable(GL_DEPTH_TEST);
  draw_lines(camera, lines);
}

void Renderer::set_slice_image(const std::vector<uint8_t>& rgba, int w, int h,
                               const std::array<Eigen::Vector3f, 4>& corners) {
  if (!ct_texture_) gl_.GenTextures(1, &ct_texture_);
  gl_.BindTexture(GL_TEXTURE_2D, ct_texture_);
  gl_.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  gl_.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  gl_.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  gl_.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  gl_.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
  gl_.TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA, w, h, 0, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
  const float uv[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  std::vector<float> data;
  for (int k : {0, 1, 2, 0, 2, 3})
    data.insert(data.end(), {corners[k].x(), corners[k].y(), corners[k].z(), uv[k][0], uv[k][1]});
  gl_.BindBuffer(GL_ARRAY_BUFFER, ct_vbo_);
  gl_.BufferSubData(GL_ARRAY_BUFFER, 0, static_cast<GLsizeiptr>(data.size() * sizeof(float)), data.data());
  slice_image_ = true;
}

void Renderer::draw_slice_image(const Camera& camera) {
  if (!ct_on_plane()) return;
  const Eigen::Matrix4f mvp = camera.projection() * camera.view();
  gl_.UseProgram(ct_program_);
  gl_.UniformMatrix4fv(gl_.GetUniformLocation(ct_program_, "u_mvp"), 1, GL_FALSE, mvp.data());
  gl_.Uniform1i(gl_.GetUniformLocation(ct_program_, "u_tex"), 0);
  gl_.ActiveTexture(GL_TEXTURE0);
  gl_.BindTexture(GL_TEXTURE_2D, ct_texture_);
  gl_.Enable(GL_DEPTH_TEST);
  gl_.DepthFunc(GL_LEQUAL);
  gl_.Disable(GL_CULL_FACE);
  // CT where the organs pass left alpha 0, the section colour over it where they left 0.45.
  gl_.Enable(GL_BLEND);
  gl_.BlendFuncSeparate(GL_ONE_MINUS_DST_ALPHA, GL_DST_ALPHA, GL_ONE, GL_ZERO);
  gl_.BindVertexArray(ct_vao_);
  gl_.DrawArrays(GL_TRIANGLES, 0, 6);
  gl_.BindVertexArray(0);
  gl_.Disable(GL_BLEND);
  gl_.DepthFunc(GL_LESS);
  // Opaque again everywhere (pictures and the window keep alpha 1).
  gl_.ColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_TRUE);
  gl_.ClearColor(0, 0, 0, 1);
  gl_.Clear(GL_COLOR_BUFFER_BIT);
  gl_.ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
}

void Renderer::prepare_imgui_fonts() {
  ImGuiIO& io = ImGui::GetIO();
  if (font_texture_) {
    io.Fonts->SetTexID(reinterpret_cast<ImTextureID>(static_cast<intptr_t>(font_texture_)));
    return;
  }
  unsigned char* pixels = nullptr;
  int w = 0, h = 0;
  io.Fonts->GetTexDataAsRGBA32(&pixels, &w, &h);
  gl_.GenTextures(1, &font_texture_);
  gl_.BindTexture(GL_TEXTURE_2D, font_texture_);
  gl_.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  gl_.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  gl_.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
  gl_.TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA, w, h, 0, GL_RGBA, GL_UNSIGNED_BYTE, pixels);
  io.Fonts->SetTexID(reinterpret_cast<ImTextureID>(static_cast<intptr_t>(font_texture_)));
}

void Renderer::draw_imgui(const ImDrawData* data) {
  if (!data || data->CmdListsCount == 0) return;
  prepare_imgui_fonts();
  const float fb_w = data->DisplaySize.x * data->FramebufferScale.x;
  const float fb_h = data->DisplaySize.y * data->FramebufferScale.y;
  if (fb_w <= 0 || fb_h <= 0) return;
  gl_.Enable(GL_BLEND);
  gl_.BlendEquation(GL_FUNC_ADD);
  gl_.BlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
  gl_.Disable(GL_CULL_FACE);
  gl_.Disable(GL_DEPTH_TEST);
  gl_.Enable(GL_SCISSOR_TEST);
  const float L = data->DisplayPos.x, R = L + data->DisplaySize.x;
  const float T = data->DisplayPos.y, B = T + data->DisplaySize.y;
  const float ortho[16] = {2.0f / (R - L),    0, 0,   0, 0, 2.0f / (T - B), 0, 0, 0, 0, -1.0f, 0, (R + L) / (L - R),
                           (T + B) / (B - T), 0, 1.0f};
  gl_.UseProgram(imgui_program_);
  gl_.Uniform1i(gl_.GetUniformLocation(imgui_program_, "u_tex"), 0);
  gl_.UniformMatrix4fv(gl_.GetUniformLocation(imgui_program_, "u_proj"), 1, GL_FALSE, ortho);
  gl_.ActiveTexture(GL_TEXTURE0);
  gl_.BindVertexArray(imgui_vao_);
  const ImVec2 clip_off = data->DisplayPos, clip_scale = data->FramebufferScale;
  for (int n = 0; n < data->CmdListsCount; ++n) {
    const ImDrawList* list = data->CmdLists[n];
    gl_.BindBuffer(GL_ARRAY_BUFFER, imgui_vbo_);
    gl_.BufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(list->VtxBuffer.Size * sizeof(ImDrawVert)),
                   list->VtxBuffer.Data, GL_STREAM_DRAW);
    gl_.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, imgui_ebo_);
    gl_.BufferData(GL_ELEMENT_ARRAY_BUFFER, static_cast<GLsizeiptr>(list->IdxBuffer.Size * sizeof(ImDrawIdx)),
                   list->IdxBuffer.Data, GL_STREAM_DRAW);
    for (int c = 0; c < list->CmdBuffer.Size; ++c) {
      const ImDrawCmd& cmd = list->CmdBuffer[c];
      if (cmd.UserCallback) {
        cmd.UserCallback(list, &cmd);
        continue;
      }
      const float x0 = (cmd.ClipRect.x - clip_off.x) * clip_scale.x;
      const float y0 = (cmd.ClipRect.y - clip_off.y) * clip_scale.y;
      const float x1 = (cmd.ClipRect.z - clip_off.x) * clip_scale.x;
      const float y1 = (cmd.ClipRect.w - clip_off.y) * clip_scale.y;
      if (x1 <= x0 || y1 <= y0) continue;
      gl_.Scissor(static_cast<int>(x0), static_cast<int>(fb_h - y1), static_cast<int>(x1 - x0),
                  static_cast<int>(y1 - y0));
      gl_.BindTexture(GL_TEXTURE_2D, static_cast<GLuint>(reinterpret_cast<intptr_t>(cmd.GetTexID())));
      gl_.DrawElements(GL_TRIANGLES, static_cast<GLsizei>(cmd.ElemCount),
                       sizeof(ImDrawIdx) == 2 ? GL_UNSIGNED_SHORT : GL_UNSIGNED_INT,
                       reinterpret_cast<void*>(static_cast<intptr_t>(cmd.IdxOffset * sizeof(ImDrawIdx))));
    }
  }
  gl_.Disable(GL_SCISSOR_TEST);
  gl_.Disable(GL_BLEND);
  gl_.BindVertexArray(0);
}

}  // namespace softatlas::app
