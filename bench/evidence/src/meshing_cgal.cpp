// All CGAL use of the evidence in one translation unit (slow to compile): reading surfaces,
// remeshing to exact face counts, Mesh_3 tetrahedralisation.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/orientation.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/remesh.h>
#include <CGAL/Polygon_mesh_processing/repair_polygon_soup.h>
#include <CGAL/Polyhedral_mesh_domain_3.h>
#include <CGAL/Polyhedron_3.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Count_stop_predicate.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/LindstromTurk.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>
#include <CGAL/IO/polygon_soup_io.h>
#include <CGAL/make_mesh_3.h>

#include <array>
#include <cmath>
#include <map>

#include "softatlas/evidence/meshing.hpp"
#include "softatlas/sim/error.hpp"

namespace softatlas::evidence {

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = K::Point_3;
using SurfaceMesh = CGAL::Surface_mesh<Point>;
namespace PMP = CGAL::Polygon_mesh_processing;
namespace SMS = CGAL::Surface_mesh_simplification;

SurfaceMesh to_cgal(const TriMesh& m) {
  SurfaceMesh sm;
  std::vector<SurfaceMesh::Vertex_index> vi;
  for (int32_t i = 0; i < m.nvert(); ++i)
    vi.push_back(sm.add_vertex(Point(m.V[3 * i], m.V[3 * i + 1], m.V[3 * i + 2])));
  for (int32_t f = 0; f < m.nface(); ++f)
    if (sm.add_face(vi[m.F[3 * f]], vi[m.F[3 * f + 1]], vi[m.F[3 * f + 2]]) == SurfaceMesh::null_face())
      throw InputError("surface", "face " + std::to_string(f) + " makes the mesh non-manifold");
  return sm;
}

TriMesh from_cgal(const SurfaceMesh& sm) {
  TriMesh m;
  std::map<SurfaceMesh::Vertex_index, int32_t> id;
  for (auto v : sm.vertices()) {
    id[v] = static_cast<int32_t>(m.V.size() / 3);
    const Point& p = sm.point(v);
    m.V.insert(m.V.end(), {p.x(), p.y(), p.z()});
  }
  for (auto f : sm.faces())
    for (auto v : CGAL::vertices_around_face(sm.halfedge(f), sm)) m.F.push_back(id[v]);
  return m;
}

}  // namespace

TriMesh read_surface(const std::string& path) {
  std::vector<Point> pts;
  std::vector<std::vector<std::size_t>> polys;
  if (!CGAL::IO::read_polygon_soup(path, pts, polys) || polys.empty())
    throw InputError(path, "cannot read a triangle surface (expected OBJ, OFF, PLY or STL with faces)");
  PMP::repair_polygon_soup(pts, polys);  // merges duplicate points, drops degenerate faces
  TriMesh m;
  for (const Point& p : pts) m.V.insert(m.V.end(), {p.x(), p.y(), p.z()});
  for (const auto& poly : polys) {
    if (poly.size() < 3) continue;
    for (size_t k = 1; k + 1 < poly.size(); ++k)  // fan-triangulate polygons
      m.F.insert(m.F.end(),
                 {static_cast<int32_t>(poly[0]), static_cast<int32_t>(poly[k]), static_cast<int32_t>(poly[k + 1])});
  }
  if (m.F.empty()) throw InputError(path, "no triangles in the file");
  return m;
}

TriMesh remesh_to_faces(const TriMesh& surface, int faces) {
  if (faces < 8) throw InputError("remesh", "expected a face count of at least 8, got " + std::to_string(faces));
  SurfaceMesh sm = to_cgal(surface);
  if (!CGAL::is_closed(sm)) throw InputError("remesh", "expected a closed surface (it has boundary edges)");
  if (!PMP::is_outward_oriented(sm)) PMP::reverse_face_orientations(sm);
  // Target edge length of an equilateral mesh with 1.3x the wanted faces: A_f = sqrt(3)/4 l^2.
  const double area = PMP::area(sm);
  const double l = std::sqrt(4.0 * area / (std::sqrt(3.0) * 1.3 * faces));
  PMP::isotropic_remeshing(sm.faces(), l, sm, CGAL::parameters::number_of_iterations(5));
  sm.collect_garbage();
  if (static_cast<int>(sm.number_of_faces()) > faces) {
    // Closed triangle mesh: E = 3F/2, so 3N/2 edges leave N faces (the predicate stops once the
    // count is below its threshold, hence + 1).
    SMS::Count_stop_predicate<SurfaceMesh> stop(static_cast<std::size_t>(3 * faces / 2 + 1));
    SMS::edge_collapse(sm, stop,
                       CGAL::parameters::get_cost(SMS::LindstromTurk_cost<SurfaceMesh>())
                           .get_placement(SMS::LindstromTurk_placement<SurfaceMesh>()));
    sm.collect_garbage();
  }
  return from_cgal(sm);
}

sim::fem::TetMesh tetrahedralize(const TriMesh& surface, double cell_size, double facet_distance,
                                 const RefineFocus* focus) {
  using Polyhedron = CGAL::Polyhedron_3<K>;
  using Domain = CGAL::Polyhedral_mesh_domain_3<Polyhedron, K>;
  using Tr = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
  using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr>;
  using Criteria = CGAL::Mesh_criteria_3<Tr>;
  std::vector<Point> pts;
  std::vector<std::array<std::size_t, 3>> tris;
  for (int32_t i = 0; i < surface.nvert(); ++i)
    pts.emplace_back(surface.V[3 * i], surface.V[3 * i + 1], surface.V[3 * i + 2]);
  for (int32_t f = 0; f < surface.nface(); ++f)
    tris.push_back({static_cast<std::size_t>(surface.F[3 * f]), static_cast<std::size_t>(surface.F[3 * f + 1]),
                    static_cast<std::size_t>(surface.F[3 * f + 2])});
  Polyhedron poly;
  PMP::polygon_soup_to_polygon_mesh(pts, tris, poly);
  if (!CGAL::is_closed(poly)) throw InputError("tetrahedralize", "expected a closed surface");
  Domain domain(poly);
  CGAL::get_default_random() = CGAL::Random(7);
  namespace P = CGAL::parameters;
  // Sizing field (Mesh_3's sizing-field concept): the cell size, smaller around the focus.
  struct Sizing {
    double base;
    RefineFocus f;
    bool on;
    K::FT operator()(const Point& p, const int, const Domain::Index&) const {
      if (!on) return base;
      const double d =
          std::sqrt(CGAL::to_double(CGAL::squared_distance(p, Point(f.centre[0], f.centre[1], f.centre[2]))));
      return std::min(base, f.size + f.grade * std::max(0.0, d - f.radius));
    }
  };
  const Sizing size{cell_size, focus ? *focus : RefineFocus{}, focus != nullptr && focus->size > 0};
  C3t3 c3t3;
  if (size.on) {
    Criteria criteria(P::facet_angle = 25, P::facet_size = size, P::facet_distance = facet_distance,
                      P::cell_radius_edge_ratio = 2.5, P::cell_size = size);
    c3t3 = CGAL::make_mesh_3<C3t3>(domain, criteria, P::no_perturb(), P::no_exude());
  } else {
    Criteria criteria(P::facet_angle = 25, P::facet_size = cell_size, P::facet_distance = facet_distance,
                      P::cell_radius_edge_ratio = 2.5, P::cell_size = cell_size);
    c3t3 = CGAL::make_mesh_3<C3t3>(domain, criteria, P::no_perturb(), P::no_exude());
  }
  sim::fem::TetMesh mesh;
  std::map<Tr::Vertex_handle, int32_t> id;
  for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c)
    for (int k = 0; k < 4; ++k) {
      auto v = c->vertex(k);
      auto it = id.find(v);
      if (it == id.end()) {
        it = id.emplace(v, static_cast<int32_t>(mesh.nodes.size() / 3)).first;
        const auto p = v->point().point();
        mesh.nodes.insert(mesh.nodes.end(), {CGAL::to_double(p.x()), CGAL::to_double(p.y()), CGAL::to_double(p.z())});
      }
      mesh.tets.push_back(it->second);
    }
  if (mesh.tets.empty()) throw InputError("tetrahedralize", "Mesh_3 produced no tetrahedra (surface not closed?)");
  return mesh;
}

}  // namespace softatlas::evidence
