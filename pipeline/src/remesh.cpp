// Stage 4, repair and remesh (CGAL). The only translation unit that includes CGAL: it compiles
// slowly, so everything CGAL is here.
//
//   polygon soup repair + orientation -> stitch borders -> fill holes -> (alpha wrap if still
//   open or self-intersecting) -> isotropic remeshing to ~(1 + overshoot) * budget faces
//   (Botsch & Kobbelt 2004, as implemented by CGAL PMP) -> shortest-edge collapse to the budget
//   (normal-change bounded, Lindstrom-Turk style queue) -> tangential relaxation -> orient
//   outward -> (alpha wrap + redo if the result self-intersects).
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/border.h>
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
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Midpoint_placement.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>
#include <CGAL/alpha_wrap_3.h>
#include <CGAL/boost/graph/helpers.h>

#include <algorithm>
#include <array>
#include <cmath>
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

// Isotropic remeshing aiming at `target_faces`, then edge collapse down to `budget` faces, then
// tangential relaxation (keeps the count, evens the angles).
Mesh remesh_to_count(const Mesh& base, int budget, const RemeshOptions& o, double* edge_out) {
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
    Mesh m = attempt == 0 ? base : first;
    PMP::isotropic_remeshing(faces(m), L, m,
                             PMP::parameters::number_of_iterations(o.remesh_iterations).protect_constraints(false));
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
  if (static_cast<int>(best.number_of_faces()) > budget) {
    // A closed triangle mesh has E = 3F/2; each collapse removes 3 edges and 2 faces.
    const std::size_t target_edges = static_cast<std::size_t>(3 * budget / 2);
    SMS::Count_stop_predicate<Mesh> stop(target_edges);
    SMS::Edge_length_cost<Mesh> cost;
    SMS::Bounded_normal_change_placement<SMS::Midpoint_placement<Mesh>> placement;
    SMS::edge_collapse(best, stop, CGAL::parameters::get_cost(cost).get_placement(placement));
    best.collect_garbage();
  }
  if (o.relaxation_iterations > 0)
    PMP::tangential_relaxation(vertices(best), best,
                               PMP::parameters::number_of_iterations(o.relaxation_iterations));
  return best;
}

}  // namespace

void surface_distance(const io::TriMesh& from, const io::TriMesh& to, double* max_mm, double* mean_mm) {
  using Triangles = std::vector<K::Triangle_3>;
  using Primitive = CGAL::AABB_triangle_primitive<K, Triangles::const_iterator>;
  using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;
  Triangles tris;
  tris.reserve(to.face_count());
  auto P = [&](int32_t v) { return Point(to.vertices[3 * v], to.vertices[3 * v + 1], to.vertices[3 * v + 2]); };
  for (size_t f = 0; f < to.face_count(); ++f) {
    K::Triangle_3 t(P(to.faces[3 * f]), P(to.faces[3 * f + 1]), P(to.faces[3 * f + 2]));
    if (!t.is_degenerate()) tris.push_back(t);
  }
  Tree tree(tris.begin(), tris.end());
  tree.accelerate_distance_queries();
  double mx = 0, sum = 0;
  for (size_t v = 0; v < from.vertex_count(); ++v) {
    const Point q(from.vertices[3 * v], from.vertices[3 * v + 1], from.vertices[3 * v + 2]);
    const double d = std::sqrt(tree.squared_distance(q));
    mx = std::max(mx, d);
    sum += d;
  }
  *max_mm = mx;
  *mean_mm = from.vertex_count() ? sum / static_cast<double>(from.vertex_count()) : 0.0;
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
                                std::to_string(components) +
                                " closed pieces can have (at least 4 faces each)");
  for (int round = 0; round < 2; ++round) {
    Mesh out = remesh_to_count(mesh, o.face_budget, o, &res.target_edge_mm);
    if (out.is_empty()) throw InputError(where, "remeshing failed to reach the face budget");
    orient_outward(out);
    res.self_intersections = PMP::does_self_intersect(out);
    res.mesh = to_trimesh(out);
    if (!res.self_intersections) break;
    if (round == 0) {
      // Thin gaps closed up during remeshing: wrap the remeshed surface tightly and redo.
      std::vector<Point> p2;
      std::vector<Polygon> f2;
      to_soup(res.mesh, &p2, &f2);
      const double a2 = std::max(0.5 * res.target_edge_mm, 0.005 * diag);
      mesh = alpha_wrap(p2, f2, a2, a2 / 30.0);
      res.repairs.push_back("self_intersections_rewrapped");
    }
  }
  double h1, m1, h2, m2;
  surface_distance(res.mesh, input, &h1, &m1);
  surface_distance(input, res.mesh, &h2, &m2);
  res.hausdorff_mm = std::max(h1, h2);
  res.mean_distance_mm = 0.5 * (m1 + m2);
  return res;
}

}  // namespace softatlas::pipeline
