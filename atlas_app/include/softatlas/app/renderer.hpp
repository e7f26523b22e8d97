// The atlas renderer: OpenGL 3.3 core through the Gl table, on either back end.
//
// Organs are indexed triangle meshes whose positions change every frame (the simulation);
// vertex normals are recomputed per frame (area-weighted, the smooth-shading normal) and
// uploaded with glBufferSubData. Opaque organs first, then context organs (transparent, depth
// write off, back to front). Back faces are culled: on llvmpipe the budget is triangle setup.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "softatlas/app/camera.hpp"
#include "softatlas/app/context.hpp"

struct ImDrawData;

namespace softatlas::app {

struct OrganStyle {
  std::array<float, 3> color{0.8f, 0.5f, 0.45f};
  float alpha = 1.0f;  // < 1: context organ (transparent)
  bool visible = true;
  bool highlight = false;
};

struct Cues {
  bool grid = true;  // grid on the posterior body wall (where organs are anchored)
  bool axes = true;  // R/A/S axis triad at the scene's corner
  std::array<float, 3> background{0.10f, 0.11f, 0.13f};
};

// A line segment for overlays (tool, force arrow), world coordinates.
struct Line {
  Eigen::Vector3f a, b;
  std::array<float, 4> color;
};

// Sectional view: the organs are cut at axis = at_mm (0 sagittal x, 1 coronal y, 2 axial z, RAS
// mm); the part above the plane (keep_below) or below it is removed, the cut shows the inside.
struct SlicePlane {
  int axis = -1;  // -1: no slice
  float at_mm = 0.0f;
  bool keep_below = true;
  bool active() const { return axis >= 0 && axis < 3; }
  Eigen::Vector4f clip() const;  // (n, d): points with n.x + d > 0 are cut away
};

// An arrow from a to b (shaft and a four-line head) appended to lines.
void add_arrow(std::vector<Line>& lines, const Eigen::Vector3f& a, const Eigen::Vector3f& b,
               const std::array<float, 4>& color);

class Renderer {
 public:
  explicit Renderer(const GlContext& context);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  // Adds an organ mesh (faces #F*3 local indices, nvert vertices); returns its index.
  int add_mesh(const std::vector<int32_t>& faces, size_t nvert);
  // New positions (#V*3, mm), normals recomputed, uploaded.
  void set_positions(int mesh, const float* xyz);
  void set_positions(int mesh, const double* xyz);
  size_t mesh_count() const { return meshes_.size(); }
  size_t face_count() const;

  // Scene bounds used by the cues (grid and axes); set once from the rest shapes.
  void set_bounds(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi);

  void begin_frame(const Cues& cues, int width, int height);
  void draw_organs(const Camera& camera, const std::vector<OrganStyle>& styles);
  void draw_cues(const Camera& camera, const Cues& cues);
  void draw_lines(const Camera& camera, const std::vector<Line>& lines);
  // The organs are cut by this plane in draw_organs; draw_slice draws the plane itself.
  void set_slice(const SlicePlane& plane) { slice_ = plane; }
  void set_depth_test(bool on);
  void draw_slice(const Camera& camera, const SlicePlane& plane);
  // The CT on the slice plane: an RGBA8 image (rows from corners[0]->corners[3], columns from
  // corners[0]->corners[1]; alpha 0 outside the CT) drawn as a textured quad at those world
  // corners. While set and the slice is active, the organ sections (the inside seen through the
  // cut) tint the CT with the organ's colour and everything else on the plane shows the CT.
  void set_slice_image(const std::vector<uint8_t>& rgba, int w, int h, const std::array<Eigen::Vector3f, 4>& corners);
  void clear_slice_image() { slice_image_ = false; }
  bool ct_on_plane() const { return slice_image_ && slice_.active(); }
  void draw_slice_image(const Camera& camera);
  // Dear ImGui draw lists (panels, labels), drawn last, with our own GL 3.3 code: Debian ships
  // imgui_impl_opengl3 only as an example source whose loader cannot see OSMesa.
  void draw_imgui(const ImDrawData* data);
  // Uploads the font atlas of the current ImGui context (before its first NewFrame).
  void prepare_imgui_fonts();

 private:
  struct Mesh {
    uint32_t vao = 0, vbo = 0, ebo = 0;
    std::vector<int32_t> faces;
    std::vector<float> interleaved;  // x y z nx ny nz per vertex
    size_t nvert = 0;
    Eigen::Vector3f centroid{0, 0, 0};
  };
  void upload(Mesh& m);
  const Gl& gl_;
  std::vector<Mesh> meshes_;
  uint32_t organ_program_ = 0, line_program_ = 0, imgui_program_ = 0;
  uint32_t line_vao_ = 0, line_vbo_ = 0;
  uint32_t imgui_vao_ = 0, imgui_vbo_ = 0, imgui_ebo_ = 0, font_texture_ = 0;
  Eigen::Vector3f lo_{-100, -100, -100}, hi_{100, 100, 100};
  SlicePlane slice_;
  uint32_t ct_program_ = 0, ct_vao_ = 0, ct_vbo_ = 0, ct_texture_ = 0;
  bool slice_image_ = false;
  int width_ = 0, height_ = 0;
};

// Writes RGBA8 pixels (top row first) as PNG, atomically (temp file + rename). Throws
// std::runtime_error naming the file on failure.
void write_png(const std::string& path, int width, int height, const std::vector<uint8_t>& rgba);

}  // namespace softatlas::app
