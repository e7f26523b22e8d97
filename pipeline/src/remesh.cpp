// Stage 4, repair and remesh (CGAL). The only translation unit that includes CGAL: it compiles
// slowly, so everything CGAL is here.
//
//   polygon soup repair + orientation -> stitch borders -> fill holes -> (alpha wrap if still
//   open or self-intersecting) -> isotropic remeshing to ~(1 + overshoot) * budget faces
//   (Botsch & Kobbelt 2004, as implemented by CGAL PMP) -> shortest-edge collapse to the budget
//   (normal-change bounded, Lindstrom-Turk style queue) -> tangential relaxation -> orient
//   outward -> (alpha wrap + redo if the result self-intersects)
//   -> if that is further from the input than the shape bound: two-level sizing (what it
//   misses remeshed from the input at half the edge length, up to three rounds); if still
//   further: quadric-error collapse (Garland & Heckbert 1997) from the repaired surface,
//   remeshed isotropically with its sharp edges held. A candidate replaces the isotropic mesh
//   only if closer, self-intersection free and with its triangle quality
//   -> normal offset that gives the surface its reference volume back.
#include <CGAL/AABB_face_graph_triangle_primitive.h>
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/border.h>
#include <CGAL/Polygon_mesh_processing/compute_normal.h>
#include <CGAL/Polygon_mesh_processing/detect_features.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/remesh.h>
#include <CGAL/Polygon_mesh_processing/repair_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Polygon_mesh_processing/stitch_borders.h>
#include <CGAL/Polygon_mesh_processing/tangential_relaxation.h>
#include <CGAL/Polygon_mesh_processing/triangulate_hole.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Bounded_normal_change_placement.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Count_stop_predicate.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Edge_length_cost.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/GarlandHeckbert_plane_policies.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Midpoint_placement.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>
#include <CGAL/alpha_wrap_3.h>
#include <CGAL/boost/graph/Euler_operations.h>
#include <CGAL/boost/graph/helpers.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <vector>

#include "softatlas/pipeline/remesh.hpp"
#include "softatlas/pipeline/topology.hpp"
#include "softatlas/sim/error.hpp"

namespace softatlas::pipeline {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = K::Point_3;
using Mesh = CGAL::Surface_mesh<Point>;
using Polygon = std::vector<std::size_t>;
namespace PMP = CGAL::Polygon_mesh_processing;
namespace SMS = CGAL::Surface_mesh_simplification;

void to_soup(const io::TriMesh& m, std::vector<Point>* pts, std::vector<Polygon>* polys) {
  pts->clear();
  polys->clear();
  for (size_t v = 0; v < m.vertex_count(); ++v)
    pts->emplace_back(m.vertices[3 * v], m.vertices[3 * v + 1], m.vertices[3 * v + 2]);
  for (size_t f = 0; f < m.face_count(); ++f)
    polys->push_back({static_cast<size_t>(m.faces[3 * f]), static_cast<size_t>(m.faces[3 * f + 1]),
                      static_cast<size_t>(m.faces[3 * f + 2])});
}

io::TriMesh to_trimesh(Mesh m) {
  m.collect_garbage();
  io::TriMesh out;
  out.vertices.reserve(3 * m.number_of_vertices());
  for (auto v : m.vertices()) {
    const Point& p = m.point(v);
    out.vertices.insert(out.vertices.end(), {p.x(), p.y(), p.z()});
  }
  for (auto f : m.faces())
    for (auto v : CGAL::vertices_around_face(m.halfedge(f), m)) out.faces.push_back(static_cast<int32_t>(v.idx()));
  return out;
}

double bbox_diagonal(const std::vector<Point>& pts) {
  const auto b = CGAL::bbox_3(pts.begin(), pts.end());
  const double dx = b.xmax() - b.xmin(), dy = b.ymax() - b.ymin(), dz = b.zmax() - b.zmin();
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

Mesh alpha_wrap(const std::vector<Point>& pts, const std::vector<Polygon>& polys, double alpha, double offset) {
  std::vector<std::array<size_t, 3>> tris;
  for (const auto& p : polys)
    if (p.size() == 3) tris.push_back({p[0], p[1], p[2]});
  Mesh wrap;
  CGAL::alpha_wrap_3(pts, tris, alpha, offset, wrap);
  return wrap;
}

bool is_sound(const Mesh& m) {
  return !m.is_empty() && CGAL::is_closed(m) && CGAL::is_triangle_mesh(m) && !PMP::does_self_intersect(m);
}

void orient_outward(Mesh& m) {
  if (!PMP::does_self_intersect(m))
    PMP::orient_to_bound_a_volume(m);
  else
    PMP::orient(m);
}

// A surface as an AABB tree of its triangles: distances and closest points.
class SurfaceTree {
 public:
  explicit SurfaceTree(const io::TriMesh& m) {
    tris_.reserve(m.face_count());
    auto P = [&](int32_t v) { return Point(m.vertices[3 * v], m.vertices[3 * v + 1], m.vertices[3 * v + 2]); };
    for (size_t f = 0; f < m.face_count(); ++f) {
      K::Triangle_3 t(P(m.faces[3 * f]), P(m.faces[3 * f + 1]), P(m.faces[3 * f + 2]));
      if (!t.is_degenerate()) tris_.push_back(t);
    }
    tree_.insert(tris_.begin(), tris_.end());
    tree_.accelerate_distance_queries();
  }
  SurfaceTree(const SurfaceTree&) = delete;
  SurfaceTree& operator=(const SurfaceTree&) = delete;
  double distance(const Point& q) const { return std::sqrt(tree_.squared_distance(q)); }
  Point closest(const Point& q) const { return tree_.closest_point(q); }
  // Max and mean distance from the vertices of `from` to this surface.
  void distances_from(const io::TriMesh& from, double* max_mm, double* mean_mm) const {
    double mx = 0, sum = 0;
    for (size_t v = 0; v < from.vertex_count(); ++v) {
      const double d = distance(Point(from.vertices[3 * v], from.vertices[3 * v + 1], from.vertices[3 * v + 2]));
      mx = std::max(mx, d);
      sum += d;
    }
    *max_mm = mx;
    *mean_mm = from.vertex_count() ? sum / static_cast<double>(from.vertex_count()) : 0.0;
  }

 private:
  using Triangles = std::vector<K::Triangle_3>;
  using Primitive = CGAL::AABB_triangle_primitive<K, Triangles::const_iterator>;
  Triangles tris_;
  CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>> tree_;
};

// Symmetric vertex-sampled Hausdorff distance and mean distance between `out` and the input.
void shape_distance(const io::TriMesh& out, const io::TriMesh& input, const SurfaceTree& input_tree,
                    double* hausdorff_mm, double* mean_mm) {
  double h1, m1, h2, m2;
  input_tree.distances_from(out, &h1, &m1);
  SurfaceTree(out).distances_from(input, &h2, &m2);
  *hausdorff_mm = std::max(h1, h2);
  *mean_mm = 0.5 * (m1 + m2);
}

// Edge collapse down to `faces` faces (a closed triangle mesh has E = 3F/2; each collapse
// removes 3 edges and 2 faces), cheapest first by `cost`.
using Bounded_midpoint = SMS::Bounded_normal_change_placement<SMS::Midpoint_placement<Mesh>>;

template <class Cost, class Placement>
void collapse_to_faces(Mesh& m, std::size_t faces, const Cost& cost, const Placement& placement) {
  SMS::Count_stop_predicate<Mesh> stop(3 * faces / 2);
  SMS::edge_collapse(m, stop, CGAL::parameters::get_cost(cost).get_placement(placement));
  m.collect_garbage();
}

// A candidate mesh's symmetric Hausdorff distance to the input, or infinity if it does not
// qualify to replace the isotropic mesh: >= 99 % of its triangles at >= 20 degrees (the
// isotropic route's quality) and free of self-intersections.
double qualified_distance(const Mesh& m, const io::TriMesh& input, const SurfaceTree& input_tree) {
  const io::TriMesh t = to_trimesh(m);
  if (inspect_surface(t).share_angle_ge_20 < 0.99 || PMP::does_self_intersect(m))
    return std::numeric_limits<double>::infinity();
  double h, mean;
  shape_distance(t, input, input_tree, &h, &mean);
  return h;
}

// Isotropic remeshing aiming at `target_faces`, then edge collapse down to `budget` faces, then
// tangential relaxation (keeps the count, evens the angles).
// Edges sharper than `keep_sharp_deg` (0 = none) are constraints: split and moved only along
// their own polyline, so a tip's rim or a cut's edge stays where it is.
Mesh remesh_to_count(const Mesh& input, int budget, const RemeshOptions& o, double keep_sharp_deg, double* edge_out) {
  Mesh base = input;
  auto keep = base.add_property_map<Mesh::Edge_index, bool>("e:keep", false).first;
  if (keep_sharp_deg > 0) PMP::detect_sharp_edges(base, keep_sharp_deg, keep);
  const double area = PMP::area(base);
  // Equilateral triangles of edge L have area sqrt(3)/4 L^2; remeshing lands near that, so aim
  // 8 % above the budget and collapse the rest.
  double target = budget * 1.08;
  double L = std::sqrt(4.0 * area / (std::sqrt(3.0) * target));
  Mesh best;
  bool have = false;
  // The first pass starts from the (possibly very fine) stage-3 surface; later passes only
  // correct the edge length and start from the first pass, so that the projection tree on the
  // fine input is built once (large CTs give million-face surfaces).
  Mesh first;
  for (int attempt = 0; attempt < 6; ++attempt) {
    Mesh m;
    if (attempt == 0)
      m = std::move(base);  // used once: later attempts start from the first pass
    else
      m = first;
    PMP::isotropic_remeshing(faces(m), L, m,
                             PMP::parameters::number_of_iterations(o.remesh_iterations)
                                 .protect_constraints(false)
                                 .edge_is_constrained_map(m.property_map<Mesh::Edge_index, bool>("e:keep").first));
    m.collect_garbage();
    if (attempt == 0) first = m;
    const double F = static_cast<double>(m.number_of_faces());
    if (F >= budget) {
      if (!have || F < best.number_of_faces()) best = m, have = true;
      if (F <= budget * 1.25) break;
    }
    // Face count scales as 1/L^2.
    L *= std::sqrt(F / target);
    if (F < budget) L *= 0.97;
  }
  if (!have) return Mesh();
  *edge_out = L;
  if (static_cast<int>(best.number_of_faces()) > budget)
    collapse_to_faces(best, budget, SMS::Edge_length_cost<Mesh>(), Bounded_midpoint());
  if (o.relaxation_iterations > 0)
    PMP::tangential_relaxation(vertices(best), best,
                               PMP::parameters::number_of_iterations(o.relaxation_iterations)
                                   .edge_is_constrained_map(best.property_map<Mesh::Edge_index, bool>("e:keep").first));
  auto kept = best.property_map<Mesh::Edge_index, bool>("e:keep").first;
  best.remove_property_map(kept);
  return best;
}

// The points of the input that a mesh misses, and the test "is p within `radius` of one of
// them" (a hash grid of cell `radius`).
class MissedPoints {
 public:
  MissedPoints(const std::vector<Point>& pts, double radius) : r_(radius) {
    for (const Point& p : pts) cells_[key(cell(p.x()), cell(p.y()), cell(p.z()))].push_back(p);
  }
  bool near(const Point& p) const {
    const long i = cell(p.x()), j = cell(p.y()), k = cell(p.z());
    for (long a = i - 1; a <= i + 1; ++a)
      for (long b = j - 1; b <= j + 1; ++b)
        for (long c = k - 1; c <= k + 1; ++c) {
          const auto it = cells_.find(key(a, b, c));
          if (it == cells_.end()) continue;
          for (const Point& q : it->second)
            if (CGAL::squared_distance(p, q) <= r_ * r_) return true;
        }
    return false;
  }

 private:
  long cell(double x) const { return static_cast<long>(std::floor(x / r_)); }
  static long long key(long i, long j, long k) {
    return ((static_cast<long long>(i) & 0x1fffff) << 42) | ((static_cast<long long>(j) & 0x1fffff) << 21) |
           (static_cast<long long>(k) & 0x1fffff);
  }
  double r_;
  std::unordered_map<long long, std::vector<Point>> cells_;
};

// Shortest edge first relative to the local target size: the collapse to the budget takes
// edges where the mesh is coarse as readily as where it was refined.
struct Sized_length_cost {
  const MissedPoints* missed;
  double fine_mm, coarse_mm;
  template <class Profile>
  boost::optional<typename Profile::FT> operator()(const Profile& p,
                                                   const boost::optional<typename Profile::Point>&) const {
    const double size = missed->near(CGAL::midpoint(p.p0(), p.p1())) ? fine_mm : coarse_mm;
    return CGAL::squared_distance(p.p0(), p.p1()) / (size * size);
  }
};

// Two-level sizing (CGAL 5.5's isotropic remeshing takes one edge length per call): the faces
// of the fine input near what the isotropic mesh missed (a thin tip) are remeshed at half the
// edge length first, the rest at the length that brings the total just above the budget (its
// border with the refined part is a constraint, split and collapsed along itself); then the
// collapse to the budget by size-relative length, relaxation with the vertices projected back
// onto the input. Empty if the refined part alone would take most of the budget.
Mesh remesh_two_level(const Mesh& input, int budget, const RemeshOptions& o, const MissedPoints& missed, double edge_mm,
                      const SurfaceTree& input_tree) {
  const double fine_mm = 0.5 * edge_mm;
  Mesh m = input;
  m.collect_garbage();
  auto rest = m.add_property_map<Mesh::Face_index, bool>("f:rest", false).first;
  std::vector<Mesh::Face_index> region;
  for (auto f : m.faces()) {
    bool near = false;
    for (auto v : CGAL::vertices_around_face(m.halfedge(f), m)) near = near || missed.near(m.point(v));
    if (near)
      region.push_back(f);
    else
      rest[f] = true;
  }
  if (region.empty()) return Mesh();
  PMP::isotropic_remeshing(region, fine_mm, m,
                           PMP::parameters::number_of_iterations(o.remesh_iterations).protect_constraints(false));
  std::vector<Mesh::Face_index> rest_faces;
  double rest_area = 0, refined = 0;
  for (auto f : m.faces())
    if (rest[f])
      rest_faces.push_back(f), rest_area += PMP::face_area(f, m);
    else
      ++refined;
  const double target = 1.08 * budget - refined;
  if (target < 0.3 * budget || rest_faces.empty()) return Mesh();
  double coarse_mm = std::sqrt(4.0 * rest_area / (std::sqrt(3.0) * target));
  Mesh best;
  for (int attempt = 0; attempt < 4; ++attempt) {
    Mesh c = m;  // a copy keeps the face indices
    PMP::isotropic_remeshing(rest_faces, coarse_mm, c,
                             PMP::parameters::number_of_iterations(o.remesh_iterations).protect_constraints(false));
    c.collect_garbage();
    const double F = static_cast<double>(c.number_of_faces());
    if (F >= budget) {
      if (best.is_empty() || F < best.number_of_faces()) best = c;
      if (F <= budget * 1.25) break;
    }
    coarse_mm *= std::sqrt(std::max(F - refined, 1.0) / target);
    if (F < budget) coarse_mm *= 0.97;
  }
  if (best.is_empty()) return Mesh();
  if (static_cast<int>(best.number_of_faces()) > budget)
    collapse_to_faces(best, budget, Sized_length_cost{&missed, fine_mm, coarse_mm}, Bounded_midpoint());
  if (o.relaxation_iterations > 0)
    PMP::tangential_relaxation(vertices(best), best, PMP::parameters::number_of_iterations(o.relaxation_iterations));
  for (auto v : best.vertices()) best.point(v) = input_tree.closest(best.point(v));
  orient_outward(best);
  return best;
}

// Delaunay-style edge flips where the surface is nearly flat across the edge (dihedral below
// `max_bend_deg`): the two opposite angles summing above 180 degrees mark the diagonal of a
// sliver pair; flipping it changes the shape by at most the bend. Repeated until none is left
// (at most 10 sweeps).
void flip_slivers(Mesh& m, double max_bend_deg) {
  const double cos_bend = std::cos(max_bend_deg * CGAL_PI / 180.0);
  auto opposite_angle = [&](Mesh::Halfedge_index h) {  // angle at the vertex facing h
    const Point& a = m.point(m.source(h));
    const Point& b = m.point(m.target(h));
    const Point& c = m.point(m.target(m.next(h)));
    const K::Vector_3 u = a - c, v = b - c;
    return std::atan2(std::sqrt(CGAL::cross_product(u, v).squared_length()), u * v);
  };
  for (int sweep = 0; sweep < 10; ++sweep) {
    int flips = 0;
    for (auto e : m.edges()) {
      const auto h = m.halfedge(e), g = m.opposite(h);
      if (m.is_border(h) || m.is_border(g)) continue;
      if (opposite_angle(h) + opposite_angle(g) <= CGAL_PI + 1e-9) continue;
      const auto c = m.target(m.next(h)), d = m.target(m.next(g));
      if (c == d || m.halfedge(c, d).is_valid()) continue;  // the new edge exists already
      if (m.degree(m.source(h)) <= 3 || m.degree(m.target(h)) <= 3) continue;
      const K::Vector_3 n1 = CGAL::unit_normal(m.point(m.source(h)), m.point(m.target(h)), m.point(c));
      const K::Vector_3 n2 = CGAL::unit_normal(m.point(m.source(g)), m.point(m.target(g)), m.point(d));
      if (n1 * n2 < cos_bend) continue;
      // The flipped pair must keep facing the same way (no fold in the plane).
      const K::Vector_3 f1 = CGAL::cross_product(m.point(d) - m.point(c), m.point(m.target(h)) - m.point(c));
      const K::Vector_3 f2 = CGAL::cross_product(m.point(m.source(h)) - m.point(c), m.point(d) - m.point(c));
      if (f1 * n1 <= 0 || f2 * n1 <= 0) continue;
      CGAL::Euler::flip_edge(h, m);
      ++flips;
    }
    if (flips == 0) break;
  }
}

// The quadric cost plus a small share of the squared edge length. On a flat region (the cap
// where a label is cut by the volume's edge) every collapse has zero quadric error; without a
// tie-break the collapses gather into fans of very high valence, which makes slivers and costs
// O(valence^2) per collapse (the slab liver took 15 s instead of 1).
template <class QuadricCost>
struct Quadric_cost_with_length {
  using Update_tag = CGAL::Tag_true;  // the quadrics are updated after each collapse
  const QuadricCost* quadric;
  double weight;  // per mm^2 of squared edge length, against the quadric's mm^2
  template <class TM, class VPM, class GT>
  void initialize(const TM& m, VPM vpm, const GT& gt) const {
    quadric->initialize(m, vpm, gt);
  }
  template <class Profile, class V>
  void update_after_collapse(const Profile& p, V v) const {
    quadric->update_after_collapse(p, v);
  }
  template <class Profile>
  boost::optional<typename Profile::FT> operator()(const Profile& p,
                                                   const boost::optional<typename Profile::Point>& placement) const {
    const boost::optional<typename Profile::FT> c = (*quadric)(p, placement);
    if (!c) return c;
    return *c + weight * CGAL::squared_distance(p.p0(), p.p1());
  }
};

// Garland & Heckbert 1997 quadric-error collapse from the repaired surface straight to the
// budget: a collapse costs the squared distances to the planes of the faces its vertex stands
// for, so flat regions give their vertices up and a thin tip or ridge keeps them (an isotropic
// mesh of the budget's edge length rounds such a tip off). The last 15 % go shortest edge first
// (needles), then sliver pairs are flipped. Empty if the input has no more faces than the budget.
Mesh quadric_to_count(const Mesh& base, int budget) {
  if (static_cast<int>(base.number_of_faces()) <= budget) return Mesh();
  Mesh m = base;
  m.collect_garbage();
  {
    using GH = SMS::GarlandHeckbert_plane_policies<Mesh, K>;
    GH gh(m);
    collapse_to_faces(m, std::lround(1.15 * budget), Quadric_cost_with_length<GH::Get_cost>{&gh.get_cost(), 0.01},
                      SMS::Bounded_normal_change_placement<GH::Get_placement>(gh.get_placement()));
  }
  // The last 15 % by shortest edge first: removes the needles the quadric leaves.
  collapse_to_faces(m, budget, SMS::Edge_length_cost<Mesh>(), Bounded_midpoint());
  orient_outward(m);
  flip_slivers(m, 20.0);
  return m;
}

// The gradient of the enclosed volume with respect to each vertex, N_v = 1/6 sum over the faces
// (v, a, b) around v of (a - v) x (b - v) = 1/3 sum of the faces' area vectors: moving v by s
// along N_v / |N_v| changes the volume by |N_v| s to first order.
std::vector<K::Vector_3> volume_gradients(const Mesh& m) {
  std::vector<K::Vector_3> g(m.number_of_vertices(), K::Vector_3(0, 0, 0));
  for (auto f : m.faces()) {
    const auto h = m.halfedge(f);
    const Mesh::Vertex_index v[3] = {m.source(h), m.target(h), m.target(m.next(h))};
    const K::Vector_3 area2 = CGAL::cross_product(m.point(v[1]) - m.point(v[0]), m.point(v[2]) - m.point(v[0]));
    for (const auto x : v) g[x.idx()] = g[x.idx()] + area2 / 6.0;
  }
  return g;
}

// The faces that intersect another face of the mesh (CGAL's box-intersection test).
std::vector<Mesh::Face_index> intersecting_faces(const Mesh& m) {
  std::vector<std::pair<Mesh::Face_index, Mesh::Face_index>> pairs;
  PMP::self_intersections(m, std::back_inserter(pairs));
  std::vector<Mesh::Face_index> out;
  for (const auto& [a, b] : pairs) out.push_back(a), out.push_back(b);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

// A coarse remesh of a label with thin gaps (a vertebra's processes 1-2 mm apart at 4 mm edges)
// can pass through itself or fold. The vertices of the crossing faces and their neighbours are
// moved halfway to the centroid of their neighbours (unfolds a fold) and pulled inward along
// their volume gradient by a small step (two crossing sheets move apart), until nothing crosses.
// Returns false (mesh unchanged) if that does not succeed within `rounds`.
bool separate_crossings(Mesh& m, double step_mm, int rounds) {
  std::vector<Point> start;
  for (auto v : m.vertices()) start.push_back(m.point(v));
  for (int round = 0; round < rounds; ++round) {
    const std::vector<Mesh::Face_index> faces_x = intersecting_faces(m);
    if (faces_x.empty()) return true;
    const std::vector<K::Vector_3> g = volume_gradients(m);
    std::vector<char> move(m.number_of_vertices(), 0);
    for (auto f : faces_x)
      for (auto v : CGAL::vertices_around_face(m.halfedge(f), m)) {
        move[v.idx()] = 1;
        for (auto u : CGAL::vertices_around_target(m.halfedge(v), m)) move[u.idx()] = 1;
      }
    std::vector<Point> next;
    for (auto v : m.vertices()) {
      Point p = m.point(v);
      if (move[v.idx()]) {
        double c[3] = {0, 0, 0};
        int k = 0;
        for (auto u : CGAL::vertices_around_target(m.halfedge(v), m))
          c[0] += m.point(u).x(), c[1] += m.point(u).y(), c[2] += m.point(u).z(), ++k;
        if (k > 0) p = Point(0.5 * (p.x() + c[0] / k), 0.5 * (p.y() + c[1] / k), 0.5 * (p.z() + c[2] / k));
        const double len = std::sqrt(g[v.idx()].squared_length());
        if (len > 0) p = p - (step_mm / len) * g[v.idx()];
      }
      next.push_back(p);
    }
    for (auto v : m.vertices()) m.point(v) = next[v.idx()];
  }
  if (!PMP::does_self_intersect(m)) return true;
  size_t i = 0;
  for (auto v : m.vertices()) m.point(v) = start[i++];
  return false;
}

// Gives a closed surface its reference volume back by a per-vertex offset along the volume
// gradient (area-weighted normal): dV = sum_v |N_v| s_v to first order. Each vertex's offset is
// capped by 0.45 x the distance to the surface's other side along its direction (a ray cast into
// the mesh's own AABB tree: two facing sheets of a thin part may both move, and still not meet)
// and by max_offset_mm in all; the uncapped vertices share the rest evenly (a water level d with
// sum_v |N_v| min(d, cap_v) = V* - V). Where the offset surface would still cross itself, the
// vertices of the crossing faces keep their place (undone locally, not for the whole surface).
// A surface that already crosses itself (reported as such) keeps the crossing faces' vertices
// where they are and must not gain new crossings. Up to five rounds, until within 0.5 %. Returns the area-weighted mean offset (mm, positive
// outward) and its largest value in *max_mm.
double restore_volume(Mesh& m, double target, double max_offset_mm, double* max_mm) {
  using Primitive = CGAL::AABB_face_graph_triangle_primitive<Mesh>;
  using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;
  m.collect_garbage();
  const size_t n = m.number_of_vertices();
  std::vector<double> total(n, 0.0);  // signed offset so far per vertex
  const std::vector<Mesh::Face_index> crossing_before = intersecting_faces(m);
  std::vector<char> frozen(n, 0);
  for (auto f : crossing_before)
    for (auto v : CGAL::vertices_around_face(m.halfedge(f), m)) frozen[v.idx()] = 1;
  auto new_crossings = [&] {
    std::vector<Mesh::Face_index> out;
    for (auto f : intersecting_faces(m))
      if (!std::binary_search(crossing_before.begin(), crossing_before.end(), f)) out.push_back(f);
    return out;
  };
  for (int round = 0; round < 5; ++round) {
    const double V = PMP::volume(m);
    if (std::abs(V - target) <= 0.005 * target) break;
    const double sign = target > V ? 1.0 : -1.0;
    const std::vector<K::Vector_3> g = volume_gradients(m);
    std::vector<double> w(n, 0.0), cap(n, 0.0);
    std::vector<K::Vector_3> dir(n, K::Vector_3(0, 0, 0));
    {
      Tree tree(faces(m).first, faces(m).second, m);
      for (auto v : m.vertices()) {
        const size_t i = v.idx();
        w[i] = std::sqrt(g[i].squared_length());
        if (w[i] <= 0) continue;
        dir[i] = (sign / w[i]) * g[i];
        const double room = max_offset_mm - sign * total[i];
        if (room <= 0 || frozen[i]) continue;
        std::vector<Mesh::Face_index> around;
        for (auto f : CGAL::faces_around_target(m.halfedge(v), m))
          if (f != Mesh::null_face()) around.push_back(f);
        const K::Ray_3 ray(m.point(v), dir[i]);
        const auto hit = tree.first_intersection(
            ray, [&](Mesh::Face_index f) { return std::find(around.begin(), around.end(), f) != around.end(); });
        double gap = std::numeric_limits<double>::infinity();
        if (hit) {
          if (const Point* p = boost::get<Point>(&hit->first))
            gap = std::sqrt(CGAL::squared_distance(*p, m.point(v)));
          else if (const K::Segment_3* sgm = boost::get<K::Segment_3>(&hit->first))
            gap = std::sqrt(std::min(CGAL::squared_distance(sgm->source(), m.point(v)),
                                     CGAL::squared_distance(sgm->target(), m.point(v))));
        }
        cap[i] = std::min(0.45 * gap, room);
      }
    }
    const double need = std::abs(target - V);
    auto gain = [&](double d) {
      double s = 0;
      for (size_t i = 0; i < n; ++i) s += w[i] * std::min(d, cap[i]);
      return s;
    };
    double lo = 0, hi = max_offset_mm;
    if (gain(hi) <= need) {
      lo = hi;
    } else {
      for (int it = 0; it < 60; ++it) {
        const double mid = 0.5 * (lo + hi);
        (gain(mid) < need ? lo : hi) = mid;
      }
    }
    const double d = lo;
    if (d < 1e-6) break;
    std::vector<Point> before;
    std::vector<double> step(n, 0.0);
    for (auto v : m.vertices()) {
      before.push_back(m.point(v));
      step[v.idx()] = std::min(d, cap[v.idx()]);
      m.point(v) = m.point(v) + step[v.idx()] * dir[v.idx()];
    }
    bool ok = false;
    for (int undo = 0; undo < 6 && !ok; ++undo) {
      const std::vector<Mesh::Face_index> crossing = new_crossings();
      ok = crossing.empty();
      for (auto f : crossing)
        for (auto v : CGAL::vertices_around_face(m.halfedge(f), m)) {
          m.point(v) = before[v.idx()];
          step[v.idx()] = 0;
        }
    }
    if (!ok) {  // give the round up
      for (auto v : m.vertices()) m.point(v) = before[v.idx()];
      break;
    }
    double moved = 0;
    for (size_t i = 0; i < n; ++i) total[i] += sign * step[i], moved += step[i];
    if (moved <= 0) break;
  }
  double area = 0, sum = 0, mx = 0;
  const std::vector<K::Vector_3> g = volume_gradients(m);
  for (size_t i = 0; i < n; ++i) {
    const double a = std::sqrt(g[i].squared_length());
    area += a, sum += a * total[i];
    if (std::abs(total[i]) > std::abs(mx)) mx = total[i];
  }
  *max_mm = mx;
  return area > 0 ? sum / area : 0.0;
}

}  // namespace

void surface_distance(const io::TriMesh& from, const io::TriMesh& to, double* max_mm, double* mean_mm) {
  SurfaceTree(to).distances_from(from, max_mm, mean_mm);
}

RemeshResult repair_and_remesh(const io::TriMesh& input, const RemeshOptions& o, const std::string& where) {
  RemeshResult res;
  if (o.face_budget < 4)
    throw InputError(where, "face budget " + std::to_string(o.face_budget) +
                                " is below what a closed surface can have (at least 4 faces)");
  std::vector<Point> pts;
  std::vector<Polygon> polys;
  to_soup(input, &pts, &polys);
  const std::vector<Point> input_pts = pts;
  const std::vector<Polygon> input_polys = polys;
  PMP::repair_polygon_soup(pts, polys);
  if (polys.empty()) throw InputError(where, "the surface has no valid triangles");
  if (!PMP::orient_polygon_soup(pts, polys)) res.repairs.push_back("nonmanifold_vertices_split");
  Mesh mesh;
  PMP::polygon_soup_to_polygon_mesh(pts, polys, mesh);
  {
    // Report what the soup repair (merging coincident points, dropping degenerate and duplicate
    // triangles) already closed.
    const size_t before = inspect_surface(input).boundary_edges;
    std::vector<Mesh::halfedge_index> border;
    PMP::border_halfedges(faces(mesh), mesh, std::back_inserter(border));
    if (before > border.size())
      res.repairs.push_back("soup_repair_closed_boundary_edges:" + std::to_string(before - border.size()));
  }

  if (!CGAL::is_closed(mesh)) {
    // Cracks between duplicated vertices (common in OBJ exports) close by stitching.
    const std::size_t stitched = PMP::stitch_borders(mesh);
    if (stitched > 0) res.repairs.push_back("stitched:" + std::to_string(stitched));
  }
  if (!CGAL::is_closed(mesh) && o.allow_hole_filling) {
    std::vector<Mesh::halfedge_index> cycles;
    PMP::extract_boundary_cycles(mesh, std::back_inserter(cycles));
    // Many open pieces (e.g. cartilage rings) are not holes in one surface: leave them to the
    // alpha wrap below instead of capping each ring.
    if (cycles.size() <= 64) {
      for (auto h : cycles) {
        std::vector<Mesh::face_index> added;
        PMP::triangulate_hole(mesh, h, std::back_inserter(added));
      }
      res.repairs.push_back("holes_filled:" + std::to_string(cycles.size()));
    }
  }
  const double diag = bbox_diagonal(input_pts);
  const double alpha = o.wrap_alpha_mm > 0 ? o.wrap_alpha_mm : 0.02 * diag;
  // A closed surface whose only flaw is self-contact (discrete surfaces of labels touch
  // themselves at split non-manifold vertices) goes on to remeshing, which usually separates the
  // contact; the result is checked again below and wrapped tightly if needed. Open or broken
  // input is wrapped here.
  const bool closed_surface = !mesh.is_empty() && CGAL::is_closed(mesh) && CGAL::is_triangle_mesh(mesh);
  if (!closed_surface || (!o.tolerate_self_contact && !is_sound(mesh))) {
    // Fallback for broken input: alpha wrapping is closed, 2-manifold and intersection-free by
    // construction (Portaneri et al. 2022). The offset keeps the wrap close to the input.
    mesh = alpha_wrap(input_pts, input_polys, alpha, alpha / 30.0);
    res.repairs.push_back("alpha_wrap:" + std::to_string(alpha).substr(0, 5) + "mm");
  }
  int components = 0;
  {
    const io::TriMesh cur = to_trimesh(mesh);
    face_components(cur, &components);
  }
  if (o.face_budget < 4 * components)
    throw InputError(where, "face budget " + std::to_string(o.face_budget) + " is below what " +
                                std::to_string(components) + " closed pieces can have (at least 4 faces each)");
  const Mesh repaired = mesh;
  Mesh chosen;
  for (int round = 0; round < 2; ++round) {
    chosen = remesh_to_count(mesh, o.face_budget, o, 0.0, &res.target_edge_mm);
    if (chosen.is_empty()) throw InputError(where, "remeshing failed to reach the face budget");
    orient_outward(chosen);
    res.self_intersections = PMP::does_self_intersect(chosen);
    if (!res.self_intersections) break;
    if (round == 0) {
      // Thin gaps closed up during remeshing: wrap the remeshed surface tightly and redo.
      std::vector<Point> p2;
      std::vector<Polygon> f2;
      to_soup(to_trimesh(chosen), &p2, &f2);
      const double a2 = std::max(0.5 * res.target_edge_mm, 0.005 * diag);
      mesh = alpha_wrap(p2, f2, a2, a2 / 30.0);
      res.repairs.push_back("self_intersections_rewrapped");
    }
  }
  const SurfaceTree input_tree(input);
  double mean;
  shape_distance(to_trimesh(chosen), input, input_tree, &res.hausdorff_mm, &mean);
  res.isotropic_hausdorff_mm = res.hausdorff_mm;
  if (o.max_hausdorff_mm > 0 && res.hausdorff_mm > o.max_hausdorff_mm) {
    // Where the mesh misses the input by more than 0.8 x the bound (a thin tip, a cut's rim)
    // gets half the edge length (two-level sizing); up to three rounds, each adding what the
    // last one still missed.
    std::vector<Point> missed;
    std::vector<char> is_missed(input.vertex_count(), 0);
    Mesh last = chosen;
    for (int round = 0; round < 3 && res.hausdorff_mm > o.max_hausdorff_mm; ++round) {
      {
        const SurfaceTree last_tree(to_trimesh(last));
        for (size_t v = 0; v < input.vertex_count(); ++v) {
          const Point p(input.vertices[3 * v], input.vertices[3 * v + 1], input.vertices[3 * v + 2]);
          if (!is_missed[v] && last_tree.distance(p) > 0.8 * o.max_hausdorff_mm) missed.push_back(p), is_missed[v] = 1;
        }
      }
      const MissedPoints near(missed, res.target_edge_mm);
      Mesh two = remesh_two_level(repaired, o.face_budget, o, near, res.target_edge_mm, input_tree);
      if (two.is_empty()) break;
      const double h_two = qualified_distance(two, input, input_tree);
      if (h_two < res.hausdorff_mm) {
        chosen = two;
        res.hausdorff_mm = h_two;
        res.simplification = "isotropic_two_level";
      }
      last = std::move(two);
    }
  }
  if (o.max_hausdorff_mm > 0 && res.hausdorff_mm > o.max_hausdorff_mm) {
    // The quadric mesh keeps the shape but has slivers that the physics pays for (the slab
    // liver's implicit solid step ran 2.4x slower and drifted 2.5 mm at rest on it). It only
    // seeds an isotropic remeshing that holds its sharp edges (the tip's rim, the cut's edge),
    // taken when it is within the bound with the triangle quality of the isotropic route.
    const Mesh q = quadric_to_count(repaired, o.face_budget);
    if (!q.is_empty() && !PMP::does_self_intersect(q)) {
      for (const double sharp_deg : {45.0, 30.0}) {
        double edge;
        Mesh even = remesh_to_count(q, o.face_budget, o, sharp_deg, &edge);
        if (even.is_empty()) continue;
        orient_outward(even);
        if (qualified_distance(even, input, input_tree) > o.max_hausdorff_mm) continue;
        chosen = std::move(even);
        res.simplification = "garland_heckbert+isotropic";
        res.target_edge_mm = edge;
        break;
      }
    }
  }
  // The chosen mesh may be a candidate that replaced a crossing isotropic mesh: ask again.
  res.self_intersections = PMP::does_self_intersect(chosen);
  chosen.collect_garbage();
  if (res.self_intersections && separate_crossings(chosen, 0.05 * res.target_edge_mm, 10)) {
    res.self_intersections = false;
    res.repairs.push_back("crossings_separated");
  }
  if (o.target_volume_mm3 > 0 && o.max_offset_mm > 0)
    res.volume_offset_mm = restore_volume(chosen, o.target_volume_mm3, o.max_offset_mm, &res.volume_offset_max_mm);
  res.mesh = to_trimesh(chosen);
  shape_distance(res.mesh, input, input_tree, &res.hausdorff_mm, &res.mean_distance_mm);
  return res;
}

}  // namespace softatlas::pipeline
