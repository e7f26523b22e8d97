#include "softatlas/app/picking.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <limits>

namespace softatlas::app {

int PickBvh::add_mesh(const std::vector<int32_t>& faces, size_t /*nvert*/) {
  const int organ = static_cast<int>(faces_.size());
  faces_.push_back(faces);
  for (size_t f = 0; f < faces.size() / 3; ++f) {
    tri_organ_.push_back(organ);
    tri_local_.push_back(static_cast<int32_t>(f));
  }
  return organ;
}

void PickBvh::fetch(int32_t tri, Eigen::Vector3f& a, Eigen::Vector3f& b, Eigen::Vector3f& c) const {
  const int32_t o = tri_organ_[static_cast<size_t>(tri)], f = tri_local_[static_cast<size_t>(tri)];
  const int32_t* idx = &faces_[static_cast<size_t>(o)][3 * static_cast<size_t>(f)];
  const float* p = pos_[static_cast<size_t>(o)];
  a = Eigen::Map<const Eigen::Vector3f>(p + 3 * idx[0]);
  b = Eigen::Map<const Eigen::Vector3f>(p + 3 * idx[1]);
  c = Eigen::Map<const Eigen::Vector3f>(p + 3 * idx[2]);
}

void PickBvh::build(const std::vector<const float*>& positions) {
  pos_ = positions;
  const int32_t n = static_cast<int32_t>(tri_organ_.size());
  order_.resize(static_cast<size_t>(n));
  std::vector<Eigen::Vector3f> centroids(static_cast<size_t>(n));
  for (int32_t t = 0; t < n; ++t) {
    order_[static_cast<size_t>(t)] = t;
    Eigen::Vector3f a, b, c;
    fetch(t, a, b, c);
    centroids[static_cast<size_t>(t)] = (a + b + c) / 3.0f;
  }
  nodes_.clear();
  nodes_.reserve(static_cast<size_t>(2 * n / 4 + 8));
  if (n > 0) build_node(0, n, centroids);
  refit(positions);
}

int32_t PickBvh::build_node(int32_t begin, int32_t end, std::vector<Eigen::Vector3f>& centroids) {
  const int32_t id = static_cast<int32_t>(nodes_.size());
  nodes_.push_back(Node{});
  nodes_[static_cast<size_t>(id)].begin = begin;
  nodes_[static_cast<size_t>(id)].end = end;
  if (end - begin <= 4) return id;
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max()), hi = -lo;
  for (int32_t i = begin; i < end; ++i) {
    lo = lo.cwiseMin(centroids[static_cast<size_t>(order_[static_cast<size_t>(i)])]);
    hi = hi.cwiseMax(centroids[static_cast<size_t>(order_[static_cast<size_t>(i)])]);
  }
  int axis = 0;
  (hi - lo).maxCoeff(&axis);
  const int32_t mid = (begin + end) / 2;
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end, [&](int32_t a, int32_t b) {
    return centroids[static_cast<size_t>(a)][axis] < centroids[static_cast<size_t>(b)][axis];
  });
  const int32_t left = build_node(begin, mid, centroids);
  const int32_t right = build_node(mid, end, centroids);
  nodes_[static_cast<size_t>(id)].left = left;
  nodes_[static_cast<size_t>(id)].right = right;
  return id;
}

void PickBvh::refit(const std::vector<const float*>& positions) {
  pos_ = positions;
  if (!nodes_.empty()) refit_node(0);
}

void PickBvh::refit_node(int32_t id) {
  Node& node = nodes_[static_cast<size_t>(id)];
  if (node.left < 0) {
    node.lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
    node.hi = -node.lo;
    for (int32_t i = node.begin; i < node.end; ++i) {
      Eigen::Vector3f a, b, c;
      fetch(order_[static_cast<size_t>(i)], a, b, c);
      node.lo = node.lo.cwiseMin(a).cwiseMin(b).cwiseMin(c);
      node.hi = node.hi.cwiseMax(a).cwiseMax(b).cwiseMax(c);
    }
    return;
  }
  refit_node(node.left);
  refit_node(node.right);
  Node& n2 = nodes_[static_cast<size_t>(id)];  // the reference stays valid (no push_back here)
  const Node& l = nodes_[static_cast<size_t>(n2.left)];
  const Node& r = nodes_[static_cast<size_t>(n2.right)];
  n2.lo = l.lo.cwiseMin(r.lo);
  n2.hi = l.hi.cwiseMax(r.hi);
}

PickHit PickBvh::intersect(const Eigen::Vector3f& origin, const Eigen::Vector3f& dir, const std::vector<bool>& visible,
                           const Eigen::Vector4f& clip) const {
  PickHit hit;
  if (nodes_.empty()) return hit;
  float best = std::numeric_limits<float>::max();
  const Eigen::Vector3f inv = dir.cwiseInverse();
  int32_t stack[128];
  int sp = 0;
  stack[sp++] = 0;
  while (sp > 0) {
    const Node& node = nodes_[static_cast<size_t>(stack[--sp])];
    // Slab test (Kay-Kajiya).
    const Eigen::Vector3f t0 = (node.lo - origin).cwiseProduct(inv);
    const Eigen::Vector3f t1 = (node.hi - origin).cwiseProduct(inv);
    const float tmin = t0.cwiseMin(t1).maxCoeff(), tmax = t0.cwiseMax(t1).minCoeff();
    if (tmax < std::max(tmin, 0.0f) || tmin > best) continue;
    if (node.left >= 0) {
      stack[sp++] = node.left;
      stack[sp++] = node.right;
      continue;
    }
    for (int32_t i = node.begin; i < node.end; ++i) {
      const int32_t tri = order_[static_cast<size_t>(i)];
      const int organ = tri_organ_[static_cast<size_t>(tri)];
      if (!visible.empty() && !visible[static_cast<size_t>(organ)]) continue;
      Eigen::Vector3f a, b, c;
      fetch(tri, a, b, c);
      // Moeller-Trumbore (1997).
      const Eigen::Vector3f e1 = b - a, e2 = c - a, p = dir.cross(e2);
      const float det = e1.dot(p);
      if (std::abs(det) < 1e-12f) continue;
      const float inv_det = 1.0f / det;
      const Eigen::Vector3f s = origin - a;
      const float u = s.dot(p) * inv_det;
      if (u < 0.0f || u > 1.0f) continue;
      const Eigen::Vector3f q = s.cross(e1);
      const float v = dir.dot(q) * inv_det;
      if (v < 0.0f || u + v > 1.0f) continue;
      const float t = e2.dot(q) * inv_det;
      if (t <= 0.0f || t >= best) continue;
      const Eigen::Vector3f at = origin + t * dir;
      if (cut_away(clip, at)) continue;  // by a slice plane
      best = t;
      hit.organ = organ;
      hit.triangle = tri_local_[static_cast<size_t>(tri)];
      hit.t = t;
      hit.point = origin + t * dir;
      const float w = 1.0f - u - v;
      const int32_t* idx = &faces_[static_cast<size_t>(organ)][3 * static_cast<size_t>(hit.triangle)];
      hit.nearest_vertex = (w >= u && w >= v) ? idx[0] : (u >= v ? idx[1] : idx[2]);
    }
  }
  return hit;
}

}  // namespace softatlas::app
