// Minimum s-t cut on a voxel box: Boykov & Kolmogorov (2004) max-flow from Boost.Graph on a
// compressed-sparse-row graph (edges stored in arrays, so millions of voxels fit; an
// adjacency_list would allocate every edge's properties separately).
#include "graph_cut.hpp"

#include <boost/graph/boykov_kolmogorov_max_flow.hpp>
#include <boost/graph/compressed_sparse_row_graph.hpp>

#include <cstdint>
#include <utility>

#include "grid.hpp"

namespace softatlas::pipeline {

std::vector<char> min_cut(const VoxelCut& p) {
  using Graph = boost::compressed_sparse_row_graph<boost::directedS, boost::no_property, boost::no_property,
                                                   boost::no_property, uint32_t, uint32_t>;
  using Edge = boost::graph_traits<Graph>::edge_descriptor;
  const auto& d = p.dims;
  const uint32_t n = static_cast<uint32_t>(static_cast<size_t>(d[0]) * d[1] * d[2]);
  const uint32_t s = n, t = n + 1;
  // Out-edges of voxel v in order: its face neighbours (-x, +x, -y, +y, -z, +z), then one edge to
  // its terminal (to s with capacity 0 when v prefers the organ, i.e. the reverse of s->v;
  // otherwise to t with the preference as capacity). Then s's edges, then t's, each by voxel.
  std::vector<std::pair<uint32_t, uint32_t>> edges;
  std::vector<float> cap;
  edges.reserve(static_cast<size_t>(n) * 8);
  cap.reserve(static_cast<size_t>(n) * 8);
  std::vector<uint32_t> first(n + 1);
  auto capacity = [&](uint32_t v, uint32_t q, int axis) { return q > v ? p.edge[axis][v] : p.edge[axis][q]; };
  for (uint32_t v = 0; v < n; ++v) {
    first[v] = static_cast<uint32_t>(edges.size());
    for_each_face_neighbour(d, v, [&](size_t q, int axis) {
      edges.push_back({v, static_cast<uint32_t>(q)});
      cap.push_back(capacity(v, static_cast<uint32_t>(q), axis));
    });
    const float pref = p.preference[v];
    if (pref >= 0)
      edges.push_back({v, s}), cap.push_back(0.0f);
    else
      edges.push_back({v, t}), cap.push_back(-pref);
  }
  first[n] = static_cast<uint32_t>(edges.size());
  std::vector<uint32_t> terminal_slot(n);  // index of s->v or t->v
  for (uint32_t v = 0; v < n; ++v)
    if (p.preference[v] >= 0)
      terminal_slot[v] = static_cast<uint32_t>(edges.size()), edges.push_back({s, v}), cap.push_back(p.preference[v]);
  for (uint32_t v = 0; v < n; ++v)
    if (p.preference[v] < 0)
      terminal_slot[v] = static_cast<uint32_t>(edges.size()), edges.push_back({t, v}), cap.push_back(0.0f);
  const Graph g(boost::edges_are_sorted, edges.begin(), edges.end(), n + 2);
  std::vector<Edge> rev(edges.size());
  for (uint32_t v = 0; v < n; ++v) {
    for (uint32_t e = first[v]; e + 1 < first[v + 1]; ++e) {  // neighbour edges: find q's edge back to v
      const uint32_t q = edges[e].second;
      uint32_t back = first[q];
      while (edges[back].second != v) ++back;
      rev[e] = Edge(q, back);
    }
    const uint32_t own = first[v + 1] - 1, term = terminal_slot[v];
    rev[own] = Edge(edges[term].first, term);
    rev[term] = Edge(v, own);
  }
  edges.clear();
  edges.shrink_to_fit();
  std::vector<float> residual(cap.size());
  std::vector<Edge> pred(n + 2);
  std::vector<boost::default_color_type> color(n + 2);
  std::vector<long> dist(n + 2);
  const auto eidx = get(boost::edge_index, g);
  const auto vidx = get(boost::vertex_index, g);
  boost::boykov_kolmogorov_max_flow(
      g, boost::make_iterator_property_map(cap.begin(), eidx),
      boost::make_iterator_property_map(residual.begin(), eidx), boost::make_iterator_property_map(rev.begin(), eidx),
      boost::make_iterator_property_map(pred.begin(), vidx), boost::make_iterator_property_map(color.begin(), vidx),
      boost::make_iterator_property_map(dist.begin(), vidx), vidx, s, t);
  // Boost colours the source tree black; the sink tree white and free voxels grey go to the sink.
  std::vector<char> out(n);
  for (uint32_t v = 0; v < n; ++v) out[v] = color[v] == boost::black_color;
  return out;
}

}  // namespace softatlas::pipeline
