#include "softatlas/app/viewer.hpp"

#include <imgui.h>
#include <backends/imgui_impl_glfw.h>

#include <algorithm>
#include <cmath>

namespace softatlas::app {

namespace {

// One CT read per set folder for the process: the window rebuilds its Viewer on reset.
std::shared_ptr<const io::CtImage> load_ct(const io::OrganSet& set) {
  static std::string cached_path;
  static std::shared_ptr<const io::CtImage> cached;
  const std::string path = set.ct_path();
  if (path.empty()) return nullptr;
  if (path != cached_path || !cached) {
    cached = std::make_shared<const io::CtImage>(io::read_ct_nifti(path));
    cached_path = path;
  }
  return cached;
}

}  // namespace

std::string overlay_text(const std::string& text) {
  if (text.size() <= kOverlayChars) return text;
  size_t cut = kOverlayChars;
  while (cut > 0 && (static_cast<unsigned char>(text[cut]) & 0xC0) == 0x80) --cut;  // not inside a character
  return text.substr(0, cut) + "...";
}

Viewer::Viewer(GlContext& context, const AtlasScene& scene)
    : context_(context), scene_(scene), renderer_(std::make_unique<Renderer>(context)) {
  imgui_ = ImGui::CreateContext();
  ImGui::SetCurrentContext(imgui_);
  ImGuiIO& io = ImGui::GetIO();
  io.IniFilename = nullptr;  // no imgui.ini littering the working folder
  ImGui::StyleColorsDark();
  if (!context.headless() && context.window()) {
    ImGui_ImplGlfw_InitForOpenGL(context.window(), true);
    glfw_backend_ = true;
  }
  const size_t n = scene.view_organs().size();
  positions_.resize(n);
  centroids_.resize(n);
  std::vector<const float*> ptrs;
  for (size_t v = 0; v < n; ++v) {
    const io::OrganEntry& o = scene.set().organs[static_cast<size_t>(scene.view_organs()[v])];
    renderer_->add_mesh(o.mesh.faces, o.mesh.vertex_count());
    bvh_.add_mesh(o.mesh.faces, o.mesh.vertex_count());
    scene.positions_mm(static_cast<int>(v), positions_[v]);
    ptrs.push_back(positions_[v].data());
    OrganStyle s;
    s.color = o.color;
    s.alpha = scene.is_context(static_cast<int>(v)) ? 0.3f : 1.0f;
    styles.push_back(s);
    labeled.push_back(false);
  }
  bvh_.build(ptrs);
  set_geometry(positions_);
  ct_ = load_ct(scene.set());
  Eigen::Vector3f lo, hi;
  scene.bounds_mm(lo, hi);
  renderer_->set_bounds(lo, hi);
  camera.width = context.width();
  camera.height = context.height();
  frame_all();
}

Viewer::~Viewer() {
  ImGui::SetCurrentContext(imgui_);
  if (glfw_backend_) ImGui_ImplGlfw_Shutdown();
  ImGui::DestroyContext(imgui_);
}

void Viewer::set_geometry(const std::vector<std::vector<float>>& positions_mm) {
  std::vector<const float*> ptrs;
  for (size_t v = 0; v < positions_mm.size() && v < positions_.size(); ++v) {
    if (&positions_mm != &positions_) positions_[v] = positions_mm[v];
    renderer_->set_positions(static_cast<int>(v), positions_[v].data());
    Eigen::Vector3f c(0, 0, 0);
    const size_t nv = positions_[v].size() / 3;
    for (size_t i = 0; i < nv; ++i) c += Eigen::Map<const Eigen::Vector3f>(&positions_[v][3 * i]);
    centroids_[v] = nv ? Eigen::Vector3f(c / static_cast<float>(nv)) : c;
    ptrs.push_back(positions_[v].data());
  }
  bvh_.refit(ptrs);
}

void Viewer::set_geometry_from_scene() {
  for (size_t v = 0; v < positions_.size(); ++v) scene_.positions_mm(static_cast<int>(v), positions_[v]);
  set_geometry(positions_);
}

PickHit Viewer::pick(float px, float py) const {
  Eigen::Vector3f o, d;
  camera.ray(px, py, o, d);
  std::vector<bool> visible;
  for (const OrganStyle& s : styles) visible.push_back(s.visible);
  return bvh_.intersect(o, d, visible, slice.clip());
}

void Viewer::frame_all() {
  Eigen::Vector3f lo, hi;
  scene_.bounds_mm(lo, hi);
  camera.frame(lo, hi);
}

void Viewer::begin() {
  ImGui::SetCurrentContext(imgui_);
  camera.width = context_.width();
  camera.height = context_.height();
  ImGuiIO& io = ImGui::GetIO();
  renderer_->prepare_imgui_fonts();
  if (glfw_backend_)
    ImGui_ImplGlfw_NewFrame();
  else {
    io.DisplaySize = ImVec2(static_cast<float>(camera.width), static_cast<float>(camera.height));
    io.DeltaTime = 1.0f / 60.0f;
  }
  ImGui::NewFrame();
}

bool Viewer::label_anchor(size_t v, Eigen::Vector3f& p) const {
  if (!slice.active()) {
    p = centroids_[v];
    return true;
  }
  const Eigen::Vector4f c = slice.clip();
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  size_t kept = 0;
  const std::vector<float>& x = positions_[v];
  for (size_t i = 0; i + 2 < x.size(); i += 3) {
    const Eigen::Vector3f q(x[i], x[i + 1], x[i + 2]);
    if (cut_away(c, q)) continue;
    sum += q.cast<double>();
    ++kept;
  }
  if (kept == 0) return false;
  p = (sum / static_cast<double>(kept)).cast<float>();
  return true;
}

void Viewer::update_slice_image() {
  if (!ct_ || !slice.active()) {
    ct_slice_ = SlicePlane{};
    return renderer_->clear_slice_image();
  }
  if (ct_slice_.active() && ct_slice_.axis == slice.axis && ct_slice_.at_mm == slice.at_mm) return;
  ct_slice_ = slice;
  // The plane over the CT's world box; texels about the CT's finest voxel spacing (<= 1024).
  const io::CtImage& ct = *ct_;
  const auto b = ct.world_bounds();
  const int a = slice.axis, u = (a + 1) % 3, v = (a + 2) % 3;
  if (slice.at_mm < b[a] - 0.5 || slice.at_mm > b[a + 3] + 0.5) return renderer_->clear_slice_image();
  double spacing = 1e9;
  for (int c = 0; c < 3; ++c) {
    const auto& m = ct.ijk_to_ras;
    spacing = std::min(spacing, std::sqrt(m[c] * m[c] + m[4 + c] * m[4 + c] + m[8 + c] * m[8 + c]));
  }
  const double lu = b[u] - 0.5 * spacing, hu = b[u + 3] + 0.5 * spacing, lv = b[v] - 0.5 * spacing,
               hv = b[v + 3] + 0.5 * spacing;
  const int w = std::clamp(static_cast<int>(std::ceil((hu - lu) / spacing)), 2, 1024);
  const int h = std::clamp(static_cast<int>(std::ceil((hv - lv) / spacing)), 2, 1024);
  const io::CtRecord& rec = *scene_.set().ct;
  const double lo_hu = rec.window_level_hu - 0.5 * rec.window_width_hu;
  std::vector<uint8_t> rgba(static_cast<size_t>(w) * h * 4, 0);
  std::array<double, 3> p{};
  p[a] = slice.at_mm;
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i) {
      p[u] = lu + (i + 0.5) * (hu - lu) / w;
      p[v] = lv + (j + 0.5) * (hv - lv) / h;
      float x;
      if (!ct.sample(p, &x)) continue;
      const uint8_t g =
          static_cast<uint8_t>(std::lround(255.0 * std::clamp((x - lo_hu) / rec.window_width_hu, 0.0, 1.0)));
      uint8_t* px = &rgba[4 * (static_cast<size_t>(j) * w + i)];
      px[0] = px[1] = px[2] = g;
      px[3] = 255;
    }
  std::array<Eigen::Vector3f, 4> corners;
  for (int k = 0; k < 4; ++k) {
    corners[k][a] = slice.at_mm;
    corners[k][u] = static_cast<float>((k == 1 || k == 2) ? hu : lu);
    corners[k][v] = static_cast<float>(k >= 2 ? hv : lv);
  }
  renderer_->set_slice_image(rgba, w, h, corners);
}

void Viewer::end() {
  renderer_->set_slice(slice);
  update_slice_image();
  renderer_->begin_frame(cues, camera.width, camera.height);
  renderer_->draw_cues(camera, cues);
  renderer_->draw_organs(camera, styles);
  renderer_->draw_slice_image(camera);
  renderer_->draw_slice(camera, slice);
  // Overlays (tool, force arrow) on top: the tissue pulled toward the hand would hide them.
  renderer_->set_depth_test(false);
  renderer_->draw_lines(camera, lines);
  renderer_->set_depth_test(true);
  // Labels under the ImGui windows (help, panel), over the 3-D view.
  ImDrawList* fg = ImGui::GetBackgroundDrawList();
  auto label = [&](const Eigen::Vector3f& p, const std::string& full, ImU32 col) {
    const std::string text = overlay_text(full);
    float x, y;
    if (!camera.project(p, x, y)) return;
    const ImVec2 size = ImGui::CalcTextSize(text.c_str());
    const ImVec2 a(x - size.x * 0.5f - 4, y - size.y * 0.5f - 2), b(x + size.x * 0.5f + 4, y + size.y * 0.5f + 2);
    fg->AddRectFilled(a, b, IM_COL32(0, 0, 0, 150), 3.0f);
    fg->AddText(ImVec2(a.x + 4, a.y + 2), col, text.c_str());
  };
  // Labels people read (display names) with leader lines: each label is pushed out from the
  // labelled organs' common centre, 60 px beyond its organ's centroid, then moved along y until
  // it overlaps no label placed before it; a line joins it to the centroid.
  struct Tag {
    ImVec2 anchor, pos, size;
    std::string text;
  };
  std::vector<Tag> tags;
  for (size_t v = 0; v < styles.size(); ++v) {
    if (!styles[v].visible) continue;
    const std::string text = overlay_text(scene_.display_name(static_cast<int>(v)));
    const bool hover = hover_names && static_cast<int>(v) == hovered;
    Eigen::Vector3f anchor;
    if ((!labeled[v] && !hover) || !label_anchor(v, anchor)) continue;
    if (labeled[v]) {
      float x, y;
      if (camera.project(anchor, x, y))
        tags.push_back({ImVec2(x, y), ImVec2(x, y), ImGui::CalcTextSize(text.c_str()), text});
    } else {
      label(anchor, text, IM_COL32(255, 255, 255, 255));
    }
  }
  if (!tags.empty()) {
    ImVec2 c(0, 0);
    for (const Tag& t : tags) c = ImVec2(c.x + t.anchor.x / tags.size(), c.y + t.anchor.y / tags.size());
    for (Tag& t : tags) {
      float dx = t.anchor.x - c.x, dy = t.anchor.y - c.y;
      const float len = std::sqrt(dx * dx + dy * dy);
      if (len < 1.0f)
        dx = 0, dy = -1;
      else
        dx /= len, dy /= len;
      t.pos = ImVec2(t.anchor.x + 60.0f * dx - 0.5f * t.size.x, t.anchor.y + 60.0f * dy - 0.5f * t.size.y);
    }
    std::sort(tags.begin(), tags.end(), [](const Tag& a, const Tag& b) { return a.pos.y < b.pos.y; });
    std::vector<Tag*> placed;
    const float pad = 6.0f;
    for (Tag& t : tags) {
      for (int guard = 0; guard < 64; ++guard) {
        bool hit = false;
        for (const Tag* o : placed)
          if (t.pos.x < o->pos.x + o->size.x + 2 * pad && o->pos.x < t.pos.x + t.size.x + 2 * pad &&
              t.pos.y < o->pos.y + o->size.y + pad && o->pos.y < t.pos.y + t.size.y + pad) {
            t.pos.y = o->pos.y + o->size.y + pad;
            hit = true;
          }
        if (!hit) break;
      }
      t.pos.x = std::clamp(t.pos.x, 4.0f, static_cast<float>(camera.width) - t.size.x - 12.0f);
      t.pos.y = std::clamp(t.pos.y, 4.0f, static_cast<float>(camera.height) - t.size.y - 8.0f);
      placed.push_back(&t);
    }
    for (const Tag& t : tags) {
      const ImVec2 a(t.pos.x - 4, t.pos.y - 2), b(t.pos.x + t.size.x + 4, t.pos.y + t.size.y + 2);
      const ImVec2 end(std::clamp(t.anchor.x, a.x, b.x), std::clamp(t.anchor.y, a.y, b.y));
      fg->AddLine(t.anchor, end, IM_COL32(235, 235, 235, 200), 1.5f);
      fg->AddCircleFilled(t.anchor, 3.0f, IM_COL32(255, 255, 255, 230));
      fg->AddRectFilled(a, b, IM_COL32(0, 0, 0, 170), 3.0f);
      fg->AddText(t.pos, IM_COL32(255, 255, 255, 255), t.text.c_str());
    }
  }
  for (const auto& [p, text] : texts) label(p, text, IM_COL32(255, 230, 120, 255));
  if (!caption.title.empty() || !caption.text.empty() || !caption.status.empty()) {
    const float w = static_cast<float>(camera.width);
    ImGui::SetNextWindowPos(ImVec2(10, 10));
    ImGui::SetNextWindowSizeConstraints(ImVec2(std::min(520.0f, w - 20), 0), ImVec2(std::min(520.0f, w - 20), 400));
    ImGui::SetNextWindowBgAlpha(0.7f);
    ImGui::Begin("##caption", nullptr,
                 ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_NoInputs | ImGuiWindowFlags_NoSavedSettings |
                     ImGuiWindowFlags_AlwaysAutoResize);
    if (!caption.title.empty()) {
      ImGui::PushStyleColor(ImGuiCol_Text, ImVec4(0.6f, 0.85f, 1.0f, 1.0f));
      ImGui::TextWrapped("%s", overlay_text(caption.title).c_str());
      ImGui::PopStyleColor();
    }
    if (!caption.text.empty()) ImGui::TextWrapped("%s", overlay_text(caption.text).c_str());
    if (!caption.status.empty()) {
      ImGui::PushStyleColor(ImGuiCol_Text,
                            caption.ok ? ImVec4(0.4f, 1.0f, 0.4f, 1.0f) : ImVec4(1.0f, 0.45f, 0.4f, 1.0f));
      ImGui::TextWrapped("%s", overlay_text(caption.status).c_str());
      ImGui::PopStyleColor();
    }
    ImGui::End();
  }
  ImGui::Render();
  renderer_->draw_imgui(ImGui::GetDrawData());
}

void Viewer::save_png(const std::string& path) const {
  write_png(path, context_.width(), context_.height(), context_.read_rgba());
}

}  // namespace softatlas::app
