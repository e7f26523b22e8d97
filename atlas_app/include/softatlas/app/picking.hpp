// Picking: a ray against the current (deformed) organ meshes.
//
// A bounding-volume hierarchy over every triangle of every organ is built once (median split on
// triangle centroids) and refitted each frame: the topology never changes, only the positions,
// so refitting (boxes recomputed bottom-up, O(#F)) keeps it valid without a rebuild.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace softatlas::app {

// A slice plane's clip (n, d) (SlicePlane::clip) cuts point p away when n.p + d > 0.
inline bool cut_away(const Eigen::Vector4f& clip, const Eigen::Vector3f& p) {
  return clip.head<3>().dot(p) + clip[3] > 0.0f;
}

struct PickHit {
  int organ = -1;           // index of the organ mesh (as added), -1: no hit
  int triangle = -1;        // local face index in that organ
  int nearest_vertex = -1;  // local vertex of that face closest to the point
  float t = 0.0f;           // ray parameter (distance along the unit direction)
  Eigen::Vector3f point{0, 0, 0};
};

class PickBvh {
 public:
  // Adds an organ mesh (local faces #F*3); call build() after the last one.
  int add_mesh(const std::vector<int32_t>& faces, size_t nvert);
  void build(const std::vector<const float*>& positions);  // #V*3 per organ
  void refit(const std::vector<const float*>& positions);  // same topology, new positions
  // Closest hit along the ray; organs with visible[o] == false are skipped (empty: all), and so
  // are points p cut away by a slice plane (clip.xyz . p + clip.w > 0; the default cuts nothing).
  PickHit intersect(const Eigen::Vector3f& origin, const Eigen::Vector3f& dir, const std::vector<bool>& visible = {},
                    const Eigen::Vector4f& clip = Eigen::Vector4f(0, 0, 0, -1)) const;
  size_t triangle_count() const { return tri_organ_.size(); }

 private:
  struct Node {
    Eigen::Vector3f lo = Eigen::Vector3f::Zero(), hi = Eigen::Vector3f::Zero();
    int32_t left = -1, right = -1;  // children; -1 for a leaf
    int32_t begin = 0, end = 0;     // leaf: range in order_
  };
  void fetch(int32_t tri, Eigen::Vector3f& a, Eigen::Vector3f& b, Eigen::Vector3f& c) const;
  int32_t build_node(int32_t begin, int32_t end, std::vector<Eigen::Vector3f>& centroids);
  void refit_node(int32_t node);

  std::vector<std::vector<int32_t>> faces_;
  std::vector<const float*> pos_;
  std::vector<int32_t> tri_organ_, tri_local_;
  std::vector<int32_t> order_;
  std::vector<Node> nodes_;
};

}  // namespace softatlas::app
