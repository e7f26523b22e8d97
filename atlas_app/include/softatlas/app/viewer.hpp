// Viewer: ties a GL context, the renderer, the picking BVH and Dear ImGui to an AtlasScene.
// The same object draws the window (GLFW), headless screenshots (OSMesa), lesson pictures and
// the render benchmark.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "softatlas/app/camera.hpp"
#include "softatlas/app/context.hpp"
#include "softatlas/app/picking.hpp"
#include "softatlas/app/renderer.hpp"
#include "softatlas/app/scene.hpp"
#include "softatlas/io/ct_image.hpp"

struct ImGuiContext;

namespace softatlas::app {

// Text as an overlay shows it (captions, labels, questions, the end screen): at most
// kOverlayChars bytes, cut at a UTF-8 character boundary with "..." appended. An ImGui draw list
// holds 65,536 vertices (4 per glyph): a 100,000-character line aborted `lesson run` (issue 17).
constexpr size_t kOverlayChars = 3000;
std::string overlay_text(const std::string& text);

struct Caption {
  std::string title;   // lesson / step name
  std::string text;    // what the lesson says
  std::string status;  // pass / fail line
  bool ok = true;
};

class Viewer {
 public:
  Viewer(GlContext& context, const AtlasScene& scene);
  ~Viewer();
  Viewer(const Viewer&) = delete;
  Viewer& operator=(const Viewer&) = delete;

  // Per view organ positions (mm, #V*3); refits the picking BVH and uploads to the renderer.
  void set_geometry(const std::vector<std::vector<float>>& positions_mm);
  void set_geometry_from_scene();          // same, read from scene.state (single-threaded callers)
  PickHit pick(float px, float py) const;  // pixel, top-left origin
  void frame_all();                        // camera fits the view organs

  // One frame: organs, cues, overlay lines, labels, caption; `panel` draws extra ImGui windows
  // (the interactive panel) between NewFrame and Render.
  template <class Panel>
  void render(Panel&& panel) {
    begin();
    panel();
    end();
  }
  void render() {
    begin();
    end();
  }
  std::vector<uint8_t> screenshot() const { return context_.read_rgba(); }
  void save_png(const std::string& path) const;

  Camera camera;
  Cues cues;
  std::vector<OrganStyle> styles;                              // per view organ
  std::vector<bool> labeled;                                   // per view organ: draw the name at its centroid
  std::vector<Line> lines;                                     // overlay (tool, force arrow)
  std::vector<std::pair<Eigen::Vector3f, std::string>> texts;  // world-anchored notes
  Caption caption;
  SlicePlane slice;         // sectional view (lesson `slice` steps, --slice)
  int hovered = -1;         // view organ under the mouse (window)
  bool hover_names = true;  // false during pick steps: the name would give the answer
  GlContext& context() { return context_; }
  Renderer& renderer() { return *renderer_; }
  ImGuiContext* imgui() { return imgui_; }
  // The organ set's CT (atlas.yaml `ct:`), read once; null when the set records none.
  const io::CtImage* ct() const { return ct_.get(); }
  // Where view organ v's name is anchored: its centroid, or with a slice the centroid of the part
  // the slice keeps; false when the slice removes all of it (no label for an organ not drawn).
  bool label_anchor(size_t v, Eigen::Vector3f& p) const;

 private:
  void begin();
  void end();
  GlContext& context_;
  const AtlasScene& scene_;
  std::unique_ptr<Renderer> renderer_;
  PickBvh bvh_;
  std::vector<std::vector<float>> positions_;
  std::vector<Eigen::Vector3f> centroids_;
  ImGuiContext* imgui_ = nullptr;
  bool glfw_backend_ = false;
  void update_slice_image();  // the CT resampled on `slice` (when it moved)
  std::shared_ptr<const io::CtImage> ct_;
  SlicePlane ct_slice_;  // the plane the current slice image was made for
};

}  // namespace softatlas::app
