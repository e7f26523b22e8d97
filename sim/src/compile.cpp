// The scene compiler: a SceneDesc in, a Model out, checked once, holding only what the scene
// needs. The step trusts the model (STYLE.md: "the compiler checks, the step trusts").
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <sstream>
#include <unordered_map>

#include "forces.hpp"
#include "softatlas/sim/sim.hpp"

namespace softatlas::sim {
namespace {

std::string organ_field(const SceneDesc& scene, size_t o, const std::string& field) {
  const std::string& name = scene.organs[o].name;
  return "organ '" + (name.empty() ? std::to_string(o) : name) + "': " + field;
}

std::string num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

void require(bool ok, const std::string& where, const std::string& what) {
  if (!ok) throw InputError(where, what);
}

void check_material(const SceneDesc& scene, size_t o) {
  const Material& m = scene.organs[o].material;
  auto where = [&](const char* f) { return organ_field(scene, o, std::string("material.") + f); };
  auto nonneg = [&](double v, const char* f) {
    require(std::isfinite(v) && v >= 0.0, where(f), "expected a finite value >= 0, got " + num(v));
  };
  nonneg(m.young_modulus_pa, "young_modulus_pa");
  require(std::isfinite(m.thickness_m) && m.thickness_m > 0, where("thickness_m"),
          "expected a positive thickness, got " + num(m.thickness_m));
  nonneg(m.total_mass_kg, "total_mass_kg");
  require(std::isfinite(m.density_kg_m3) && m.density_kg_m3 > 0, where("density_kg_m3"),
          "expected a positive density, got " + num(m.density_kg_m3));
  nonneg(m.stiffness, "stiffness");
  require(std::isfinite(m.damping) && m.damping >= -1.0, where("damping"),
          "expected a damping >= 0 (or -1 for 000 eq 10), got " + num(m.damping));
  nonneg(m.damping_scale, "damping_scale");
  require(std::isfinite(m.damping_ratio) && m.damping_ratio >= -1.0, where("damping_ratio"),
          "expected a damping ratio >= 0 (or -1 for 000 eq 10), got " + num(m.damping_ratio));
  nonneg(m.vertex_mass_kg, "vertex_mass_kg");
  require(std::isfinite(m.elastica_a) && m.elastica_a > 0, where("elastica_a"),
          "expected a > 0 (000 eq 5), got " + num(m.elastica_a));
  nonneg(m.elastica_b, "elastica_b");
  require(m.elastica_p == 1 || m.elastica_p == 2, where("elastica_p"),
          "expected p = 1 or 2 (000 eq 5), got " + std::to_string(m.elastica_p));
  require(std::isfinite(m.curvature_unit_m) && m.curvature_unit_m > 0, where("curvature_unit_m"),
          "expected a positive length, got " + num(m.curvature_unit_m));
  require(std::isfinite(m.elastica_cap) && m.elastica_cap > 0, where("elastica_cap"),
          "expected a positive cap of the curvature term, got " + num(m.elastica_cap));
  require(std::isfinite(m.tau_s) && m.tau_s < 1.0, where("tau_s"),
          "expected tau_s < 1 (negative = off), got " + num(m.tau_s));
  require(std::isfinite(m.tau_c) && m.tau_c < 1.0, where("tau_c"),
          "expected tau_c < 1 (negative = off), got " + num(m.tau_c));
  require(m.compensation_iterations >= 0 && m.compensation_iterations <= 1000, where("compensation_iterations"),
          "expected 0..1000");
  nonneg(m.flexion_stiffness, "flexion_stiffness");
  require(std::isfinite(m.volume_stiffness) && m.volume_stiffness >= 0 && m.volume_stiffness <= 1.0,
          where("volume_stiffness"), "expected 0..1, got " + num(m.volume_stiffness));
}

void check_mesh(const SceneDesc& scene, size_t o) {
  const OrganDesc& org = scene.organs[o];
  require(!org.name.empty(), "organ " + std::to_string(o), "organ without a name");
  require(org.vertices.size() % 3 == 0, organ_field(scene, o, "vertices"), "expected 3 coordinates per vertex");
  require(org.faces.size() % 3 == 0, organ_field(scene, o, "faces"),
          "expected 3 vertex indices per face (triangles only)");
  require(!org.faces.empty(), organ_field(scene, o, "faces"), "empty mesh: no faces");
  const size_t nv = org.vertices.size() / 3;
  for (size_t i = 0; i < org.vertices.size(); ++i)
    require(std::isfinite(org.vertices[i]), organ_field(scene, o, "vertices"),
            "non-finite coordinate at vertex " + std::to_string(i / 3));
  for (size_t f = 0; f < org.faces.size() / 3; ++f) {
    for (int c = 0; c < 3; ++c) {
      const int32_t v = org.faces[3 * f + c];
      require(v >= 0 && static_cast<size_t>(v) < nv, organ_field(scene, o, "faces"),
              "face " + std::to_string(f) + " has vertex index " + std::to_string(v) + " outside 0.." +
                  std::to_string(nv - 1));
    }
    const int32_t a = org.faces[3 * f], b = org.faces[3 * f + 1], c = org.faces[3 * f + 2];
    require(a != b && b != c && a != c, organ_field(scene, o, "faces"),
            "face " + std::to_string(f) + " repeats a vertex");
  }
  for (int32_t v : org.fixed)
    require(v >= 0 && static_cast<size_t>(v) < nv, organ_field(scene, o, "fixed"),
            "fixed vertex " + std::to_string(v) + " outside 0.." + std::to_string(nv - 1));
}

// Cuthill-McKee order of the used vertices (marked l2g[v] == 0) over the mesh graph, started
// from a pseudo-peripheral vertex of each component: neighbouring vertices get nearby indices,
// so the spring loop's scattered reads and writes stay within a narrow band of memory whatever
// order the file (or the importer) gave. Measured: docs/performance.md.
std::vector<int32_t> locality_order(size_t nv, const std::vector<int32_t>& faces, const std::vector<int32_t>& used) {
  std::vector<std::vector<int32_t>> adj(nv);
  for (size_t f = 0; f + 2 < faces.size(); f += 3)
    for (int e = 0; e < 3; ++e) {
      const int32_t a = faces[f + e], b = faces[f + (e + 1) % 3];
      adj[a].push_back(b), adj[b].push_back(a);
    }
  for (auto& l : adj) {
    std::sort(l.begin(), l.end());
    l.erase(std::unique(l.begin(), l.end()), l.end());
  }
  std::vector<int32_t> order, level(nv, -1);
  order.reserve(nv);
  auto bfs = [&](int32_t start, std::vector<int32_t>& out) {
    out.clear();
    out.push_back(start);
    level[start] = 0;
    for (size_t q = 0; q < out.size(); ++q) {
      const int32_t v = out[q];
      std::vector<int32_t> next;
      for (int32_t n : adj[v])
        if (level[n] < 0) level[n] = level[v] + 1, next.push_back(n);
      std::sort(next.begin(), next.end(), [&](int32_t a, int32_t b) { return adj[a].size() < adj[b].size(); });
      out.insert(out.end(), next.begin(), next.end());
    }
  };
  std::vector<int32_t> comp;
  for (size_t s = 0; s < nv; ++s) {
    if (used[s] != 0 || level[s] >= 0) continue;
    bfs(static_cast<int32_t>(s), comp);  // find the far end of the component
    const int32_t far = comp.back();
    for (int32_t v : comp) level[v] = -1;
    bfs(far, comp);  // and order from there
    order.insert(order.end(), comp.begin(), comp.end());
  }
  return order;
}

// Gershgorin bound on the largest eigenvalue of M^-1/2 K M^-1/2 and on the damping rate, per
// vertex; the stable explicit step of x'' = -w^2 x - c x' under symplectic Euler is
// h^2 w^2 + 2 h c < 4, i.e. h < (-c + sqrt(c^2 + 4 w^2)) / w^2 (docs/physics.md).
double estimate_stable_dt(const Model& m, const std::vector<double>& k_eff) {
  std::vector<double> w2(m.nvert, 0.0), c(m.nvert, 0.0);
  auto add = [&](int32_t a, int32_t b, double k, double d) {
    const double ma = m.vert_mass[a], mb = m.vert_mass[b];
    if (!(ma > 0) || !(mb > 0)) return;
    const double cross = 1.0 / std::sqrt(ma * mb);
    w2[a] += k / ma + k * cross, w2[b] += k / mb + k * cross;
    c[a] += d / ma + d * cross, c[b] += d / mb + d * cross;
  };
  for (int32_t s = 0; s < m.nspring; ++s) add(m.spring_a[s], m.spring_b[s], k_eff[s], m.spring_d[s]);
  for (int32_t s = 0; s < m.nconn; ++s) add(m.conn_a[s], m.conn_b[s], m.conn_k[s], m.conn_d[s]);
  for (int32_t f = 0; f < m.nflex; ++f) {
    // A dihedral spring of stiffness kf acts like a spring of about kf / l^2 on its wings.
    const int32_t a = m.flex_a[f], b = m.flex_b[f];
    const double dx = m.vert_rest_x[b] - m.vert_rest_x[a], dy = m.vert_rest_y[b] - m.vert_rest_y[a],
                 dz = m.vert_rest_z[b] - m.vert_rest_z[a];
    const double l2 = std::max(dx * dx + dy * dy + dz * dz, 1e-300);
    add(m.flex_c[f], m.flex_d[f], 4.0 * m.flex_k[f] / l2, 0.0);
  }
  double h = std::numeric_limits<double>::infinity();
  for (int32_t i = 0; i < m.nvert; ++i) {
    if (m.vert_inv_mass[i] == 0.0 || w2[i] <= 0.0) continue;
    const double hi = (-c[i] + std::sqrt(c[i] * c[i] + 4.0 * w2[i])) / w2[i];
    h = std::min(h, hi);
  }
  return h;
}

}  // namespace

const char* to_string(ModelKind kind) {
  switch (kind) {
    case ModelKind::tmsm:
      return "tmsm";
    case ModelKind::cmsm:
      return "cmsm";
    case ModelKind::nmsm:
      return "nmsm";
    case ModelKind::flexion:
      return "flexion";
    case ModelKind::solid:
      return "solid";
    case ModelKind::rigid:
      return "rigid";
  }
  return "?";
}

bool parse_model_kind(const std::string& text, ModelKind& out) {
  for (ModelKind k :
       {ModelKind::tmsm, ModelKind::cmsm, ModelKind::nmsm, ModelKind::flexion, ModelKind::solid, ModelKind::rigid})
    if (text == to_string(k)) return out = k, true;
  return false;
}

const char* to_string(Integrator integrator) {
  switch (integrator) {
    case Integrator::verlet:
      return "verlet";
    case Integrator::semi_implicit:
      return "semi-implicit";
    case Integrator::implicit:
      return "implicit";
  }
  return "?";
}

bool parse_integrator(const std::string& text, Integrator& out) {
  for (Integrator i : {Integrator::verlet, Integrator::semi_implicit, Integrator::implicit})
    if (text == to_string(i)) return out = i, true;
  if (text == "semi_implicit" || text == "symplectic") return out = Integrator::semi_implicit, true;
  return false;
}

Model compile(const SceneDesc& scene) {
  // ---- settings ----
  require(std::isfinite(scene.dt_s) && scene.dt_s >= 0 && scene.dt_s <= 1.0, "scene: dt_s",
          "expected a time step in (0, 1] s (0: the models' own), got " + num(scene.dt_s));
  require(scene.cg_iterations >= 1 && scene.cg_iterations <= 100000, "scene: cg_iterations",
          "expected 1..100000, got " + std::to_string(scene.cg_iterations));
  require(std::isfinite(scene.cg_tolerance) && scene.cg_tolerance >= 0, "scene: cg_tolerance", "expected a value >= 0");
  require(std::isfinite(scene.max_tool_force_N) && scene.max_tool_force_N > 0, "scene: max_tool_force_N",
          "expected a positive force, got " + num(scene.max_tool_force_N));
  require(scene.max_substeps >= 1 && scene.max_substeps <= 100000, "scene: max_substeps", "expected 1..100000");
  for (double g : scene.gravity_m_s2) require(std::isfinite(g), "scene: gravity_m_s2", "expected finite components");
  require(!scene.organs.empty(), "scene: organs", "expected at least one organ");
  for (size_t o = 0; o < scene.organs.size(); ++o) {
    check_mesh(scene, o);
    check_material(scene, o);
    for (size_t p = 0; p < o; ++p)
      require(scene.organs[p].name != scene.organs[o].name, organ_field(scene, o, "name"), "duplicate organ name");
  }
  const int32_t norg_in = static_cast<int32_t>(scene.organs.size());
  for (size_t c = 0; c < scene.connections.size(); ++c) {
    const ConnectionDesc& cd = scene.connections[c];
    const std::string where = "connection " + std::to_string(c);
    require(cd.organ_a >= 0 && cd.organ_a < norg_in && cd.organ_b >= 0 && cd.organ_b < norg_in, where,
            "organ index out of range");
    require(cd.vertex_a >= 0 && static_cast<size_t>(cd.vertex_a) < scene.organs[cd.organ_a].vertices.size() / 3, where,
            "vertex_a out of range for organ '" + scene.organs[cd.organ_a].name + "'");
    require(cd.vertex_b >= 0 && static_cast<size_t>(cd.vertex_b) < scene.organs[cd.organ_b].vertices.size() / 3, where,
            "vertex_b out of range for organ '" + scene.organs[cd.organ_b].name + "'");
    require(std::isfinite(cd.rest_length_m) && cd.rest_length_m >= 0, where,
            "expected a rest length >= 0, got " + num(cd.rest_length_m));
    require(std::isfinite(cd.stiffness) && cd.stiffness >= 0, where,
            "expected a stiffness >= 0, got " + num(cd.stiffness));
  }

  Model m;
  m.integrator = scene.integrator;
  m.dt_s = scene.dt_s > 0 ? scene.dt_s : recommended_dt_s(scene);  // timestep.cpp
  m.gravity = scene.gravity && (scene.gravity_m_s2[0] != 0 || scene.gravity_m_s2[1] != 0 || scene.gravity_m_s2[2] != 0);
  m.gravity_m_s2 = scene.gravity_m_s2;
  m.cg_iterations = scene.cg_iterations;
  m.cg_tolerance = scene.cg_tolerance;
  m.guard = scene.guard;
  m.max_tool_force_N = scene.max_tool_force_N;
  m.max_substeps = scene.max_substeps;
  m.allow_sleep = scene.allow_sleep;
  m.sleep_speed_m_s = scene.sleep_speed_m_s;
  m.sleep_steps = scene.sleep_steps;
  require(scene.threads >= 1 && scene.threads <= 64, "scene: threads", "expected 1..64");
  if (scene.threads > 1)
    m.plan.push_back("explicit steps: organs spread over " + std::to_string(scene.threads) + " threads");
  m.threads = scene.threads;

  // ---- which organs: shown ones and everything connected to them (transitively) ----
  std::vector<std::vector<int32_t>> adj(norg_in);
  for (const ConnectionDesc& cd : scene.connections)
    if (cd.organ_a != cd.organ_b) adj[cd.organ_a].push_back(cd.organ_b), adj[cd.organ_b].push_back(cd.organ_a);
  std::vector<char> keep(norg_in, 0);
  std::vector<int32_t> queue;
  for (int32_t o = 0; o < norg_in; ++o)
    if (scene.organs[o].shown) keep[o] = 1, queue.push_back(o);
  for (size_t q = 0; q < queue.size(); ++q)
    for (int32_t n : adj[queue[q]])
      if (!keep[n]) keep[n] = 1, queue.push_back(n);
  std::vector<int32_t> compiled_index(norg_in, -1);
  for (int32_t o = 0; o < norg_in; ++o) {
    if (!keep[o]) {
      m.dropped.push_back("organ '" + scene.organs[o].name + "': not shown and not connected to a shown organ");
      continue;
    }
    if (!scene.organs[o].shown)
      m.plan.push_back("organ '" + scene.organs[o].name +
                       "' is hidden but simulated: it is connected to a shown organ");
  }
  require(std::any_of(keep.begin(), keep.end(), [](char k) { return k; }), "scene: organs",
          "no organ is shown: nothing to simulate");

  // ---- vertices, faces, springs per organ ----
  std::vector<double> k_eff;  // stiffness seen by the stability estimate (elastica: k (a + ...))
  std::vector<std::vector<int32_t>> local_to_global(norg_in);
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  int64_t capped_springs = 0, degenerate_faces = 0;
  for (int32_t o = 0; o < norg_in; ++o) {
    if (!keep[o]) continue;
    const OrganDesc& od = scene.organs[o];
    const Material& mat = od.material;
    OrganRange r;
    r.name = od.name;
    r.source_index = o;
    r.source_vertex_count = static_cast<int32_t>(od.vertices.size() / 3);
    r.model = mat.model;
    compiled_index[o] = static_cast<int32_t>(m.organs.size());
    const int32_t corg = compiled_index[o];

    // Only vertices used by faces are simulated (meshes may carry unused interior nodes).
    const size_t nv_in = od.vertices.size() / 3, nf = od.faces.size() / 3;
    std::vector<int32_t>& l2g = local_to_global[o];
    l2g.assign(nv_in, -1);
    r.vert_begin = m.nvert;
    for (int32_t v : od.faces)
      if (l2g[v] < 0) l2g[v] = 0;  // mark used
    for (int32_t v : locality_order(nv_in, od.faces, l2g)) {
      l2g[v] = m.nvert++;
      m.vert_rest_x.push_back(od.vertices[3 * v]);
      m.vert_rest_y.push_back(od.vertices[3 * v + 1]);
      m.vert_rest_z.push_back(od.vertices[3 * v + 2]);
      m.vert_organ.push_back(corg);
      m.vert_source.push_back(static_cast<int32_t>(v));
      for (int c = 0; c < 3; ++c)
        lo[c] = std::min(lo[c], od.vertices[3 * v + c]), hi[c] = std::max(hi[c], od.vertices[3 * v + c]);
    }
    r.vert_end = m.nvert;
    if (static_cast<size_t>(r.vert_end - r.vert_begin) < nv_in)
      m.plan.push_back("organ '" + od.name + "': " + std::to_string(nv_in - (r.vert_end - r.vert_begin)) +
                       " vertices used by no face are left out");

    r.face_begin = m.nface;
    {  // faces sorted by their smallest vertex: the curvature pass then walks memory forward
      std::vector<std::array<int32_t, 3>> tri(nf);
      for (size_t f = 0; f < nf; ++f)
        for (int c = 0; c < 3; ++c) tri[f][c] = l2g[od.faces[3 * f + c]];
      std::stable_sort(tri.begin(), tri.end(), [](const auto& p, const auto& q) {
        return std::min({p[0], p[1], p[2]}) < std::min({q[0], q[1], q[2]});
      });
      for (const auto& t : tri) m.face_vert.insert(m.face_vert.end(), t.begin(), t.end());
    }
    m.nface += static_cast<int32_t>(nf);
    r.face_end = m.nface;

    const double* X = m.vert_rest_x.data();
    const double* Y = m.vert_rest_y.data();
    const double* Z = m.vert_rest_z.data();
    const int32_t* F = m.face_vert.data();

    // masses (000 eq 8)
    m.vert_mass.resize(m.nvert, 0.0);
    const double area = surface_area(X, Y, Z, F, r.face_begin, r.face_end);
    const double volume = std::abs(enclosed_volume(X, Y, Z, F, r.face_begin, r.face_end));
    r.rest_volume_m3 = enclosed_volume(X, Y, Z, F, r.face_begin, r.face_end);
    if (mat.vertex_mass_kg > 0) {
      for (int32_t v = r.vert_begin; v < r.vert_end; ++v) m.vert_mass[v] = mat.vertex_mass_kg;
    } else {
      double total = mat.total_mass_kg;
      if (!(total > 0)) {
        total = mat.density_kg_m3 * volume;
        if (!(total > 0)) {  // open or flat surface: a shell of the 000 eq 9 thickness
          total = mat.density_kg_m3 * area * mat.thickness_m;
          m.plan.push_back("organ '" + od.name + "': encloses no volume; mass from area x thickness x density");
        }
      }
      require(total > 0, organ_field(scene, o, "faces"), "surface has zero area: cannot assign mass");
      area_masses(X, Y, Z, F, r.face_begin, r.face_end, total, m.vert_mass.data());
    }
    for (size_t f = 0; f < nf; ++f)
      if (!(surface_area(X, Y, Z, F, r.face_begin + f, r.face_begin + f + 1) > 0)) ++degenerate_faces;

    // springs = unique edges, sorted by (a, b); face area sum per edge (000 eq 9)
    struct Edge {
      int32_t a, b;
      double area;
      int faces;
      int32_t wing[2];
    };
    std::vector<Edge> edges;
    edges.reserve(3 * nf);
    for (size_t f = 0; f < nf; ++f) {
      const int32_t* t = F + 3 * (r.face_begin + f);
      const double fa = surface_area(X, Y, Z, F, r.face_begin + f, r.face_begin + f + 1);
      for (int e = 0; e < 3; ++e) {
        const int32_t a = t[e], b = t[(e + 1) % 3], w = t[(e + 2) % 3];
        edges.push_back({std::min(a, b), std::max(a, b), fa, 1, {a < b ? w : -1, a < b ? -1 : w}});
      }
    }
    std::sort(edges.begin(), edges.end(),
              [](const Edge& p, const Edge& q) { return p.a != q.a ? p.a < q.a : p.b < q.b; });
    std::vector<Edge> unique;
    for (const Edge& e : edges) {
      if (!unique.empty() && unique.back().a == e.a && unique.back().b == e.b) {
        Edge& u = unique.back();
        u.area += e.area;
        ++u.faces;
        for (int s = 0; s < 2; ++s)
          if (e.wing[s] >= 0) u.wing[s] = u.wing[s] < 0 ? e.wing[s] : u.wing[s];
      } else {
        unique.push_back(e);
      }
    }
    // median edge length: near-zero edges get their 000 eq 9 denominator capped at 1e-3 of it
    std::vector<double> lens(unique.size());
    for (size_t s = 0; s < unique.size(); ++s) {
      const int32_t a = unique[s].a, b = unique[s].b;
      lens[s] =
          std::sqrt((X[b] - X[a]) * (X[b] - X[a]) + (Y[b] - Y[a]) * (Y[b] - Y[a]) + (Z[b] - Z[a]) * (Z[b] - Z[a]));
    }
    std::vector<double> sorted_lens = lens;
    std::nth_element(sorted_lens.begin(), sorted_lens.begin() + sorted_lens.size() / 2, sorted_lens.end());
    const double median_len = sorted_lens[sorted_lens.size() / 2];
    const double min_len = 1e-3 * median_len;

    // no surface springs: solid organs (sim/solid.hpp) and rigid ones (fixed context)
    if (mat.model == ModelKind::solid || mat.model == ModelKind::rigid) unique.clear();
    r.spring_begin = m.nspring;
    for (size_t s = 0; s < unique.size(); ++s) {
      const Edge& e = unique[s];
      m.spring_a.push_back(e.a);
      m.spring_b.push_back(e.b);
      m.spring_length0.push_back(lens[s]);
      double k = mat.stiffness;
      if (!(k > 0)) {
        const double l = std::max(lens[s], min_len);
        if (lens[s] < min_len) ++capped_springs;
        k = lloyd_stiffness(mat.young_modulus_pa, mat.thickness_m, e.area, l);
      }
      const double ma = m.vert_mass[e.a], mb = m.vert_mass[e.b];
      const double d = mat.damping >= 0 ? mat.damping
                       : mat.damping_ratio >= 0
                           ? mat.damping_ratio * 2.0 * std::sqrt(k * ma * mb / std::max(ma + mb, 1e-300))
                           : mat.damping_scale * spring_damping(k, ma, mb);
      m.spring_k.push_back(k);
      m.spring_d.push_back(d);
      r.damping = r.damping || d > 0;
    }
    m.nspring += static_cast<int32_t>(unique.size());
    r.spring_end = m.nspring;

    // elastica: rest elastica lengths so that the rest shape is force-free (docs/physics.md)
    r.elastica_a = mat.elastica_a;
    r.elastica_b = mat.model == ModelKind::nmsm ? mat.elastica_b : 0.0;
    r.elastica_p = mat.elastica_p;
    r.curvature_unit_m = mat.curvature_unit_m;
    r.elastica_cap = mat.elastica_cap;
    r.curvature = mat.model == ModelKind::nmsm && mat.elastica_b > 0;  // rest curvature needed
    r.elastica_frozen = mat.model == ModelKind::nmsm && !mat.elastica_literal;
    const bool nmsm_plain = mat.model == ModelKind::nmsm && !r.curvature;
    std::vector<double> hvert(m.nvert, 0.0);
    if (r.curvature) {
      const size_t nvo = r.vert_end - r.vert_begin;
      std::vector<double> lx(m.nvert, 0.0), ly(m.nvert, 0.0), lz(m.nvert, 0.0), a2(m.nvert, 0.0), kap(m.nvert, 0.0);
      accumulate_cotan_laplacian(nf, F + 3 * r.face_begin, X, Y, Z, lx.data(), ly.data(), lz.data(), a2.data());
      mean_curvature_from_laplacian(nvo, lx.data() + r.vert_begin, ly.data() + r.vert_begin, lz.data() + r.vert_begin,
                                    a2.data() + r.vert_begin, kap.data() + r.vert_begin);
      const double coef = kernels::elastica_vertex_coef(r.elastica_p, r.elastica_b, r.curvature_unit_m);
      for (int32_t v = r.vert_begin; v < r.vert_end; ++v) hvert[v] = coef * kap[v];
    }
    if (r.curvature) {
      // The cap bounds how far the curvature term may rise above its largest rest value, so the
      // rest shape stays force-free for any b (paper values of b can exceed the cap at rest).
      double rest_max = 0.0;
      for (int32_t s = r.spring_begin; s < r.spring_end; ++s) {
        const double h = hvert[m.spring_a[s]] + hvert[m.spring_b[s]];
        rest_max = std::max(rest_max, kernels::elastica_term(r.elastica_p, h));
      }
      r.elastica_cap = mat.elastica_cap + rest_max;
    }
    for (int32_t s = r.spring_begin; s < r.spring_end; ++s) {
      const int32_t a = m.spring_a[s], b = m.spring_b[s];
      double factor = 1.0;
      if (r.curvature) {
        factor = kernels::elastica_factor(r.elastica_p, r.elastica_a, hvert[a] + hvert[b], r.elastica_cap);
      } else if (nmsm_plain) {
        factor = r.elastica_a;
      }
      if (r.elastica_frozen) {
        // conservative elastica: k (l_e - l_e0) with the factor at rest is k factor (l - l0)
        m.spring_k[s] *= factor;
        m.spring_rest.push_back(m.spring_length0[s]);
        k_eff.push_back(m.spring_k[s]);
        continue;
      }
      m.spring_rest.push_back(m.spring_length0[s] * factor);
      // the stable-step estimate takes the largest factor the cap allows
      k_eff.push_back(m.spring_k[s] * (r.curvature ? r.elastica_a + r.elastica_cap : factor));
    }
    if (r.elastica_frozen) r.curvature = false;  // no curvature pass per step

    // compensation (CMSM; NMSM with tau_s as in Table III)
    r.tau_s = mat.tau_s;
    r.tau_c = mat.tau_c;
    if (mat.model == ModelKind::cmsm) {
      if (r.tau_s < 0) r.tau_s = 0.01;  // Duan et al. 2016 defaults
      if (r.tau_c < 0) r.tau_c = 0.01;
    }
    r.compensation_iterations = (r.tau_s >= 0 || r.tau_c >= 0) ? mat.compensation_iterations : 0;

    // flexion springs on interior manifold edges (paper 003, dihedral form)
    r.flex_begin = m.nflex;
    if (mat.model == ModelKind::flexion && mat.flexion_stiffness > 0) {
      for (const Edge& e : unique) {
        if (e.faces != 2 || e.wing[0] < 0 || e.wing[1] < 0) continue;
        // faces (a, b, c) and (b, a, d): wing[0] is the face where a->b runs, wing[1] b->a
        const int32_t a = e.a, b = e.b, c = e.wing[0], d = e.wing[1];
        const double pa[3] = {X[a], Y[a], Z[a]}, pb[3] = {X[b], Y[b], Z[b]}, pc[3] = {X[c], Y[c], Z[c]},
                     pd[3] = {X[d], Y[d], Z[d]};
        m.flex_a.push_back(a), m.flex_b.push_back(b), m.flex_c.push_back(c), m.flex_d.push_back(d);
        m.flex_rest_angle.push_back(dihedral_angle(pa, pb, pc, pd));
        m.flex_k.push_back(mat.flexion_stiffness);
        ++m.nflex;
      }
    }
    r.flex_end = m.nflex;
    // The volume constraint (paper 003) is a pass of its own: any surface model may use it.
    r.volume_stiffness = mat.model == ModelKind::rigid ? 0.0 : mat.volume_stiffness;

    // fixed vertices
    m.vert_inv_mass.resize(m.nvert, 0.0);
    for (int32_t v = r.vert_begin; v < r.vert_end; ++v)
      m.vert_inv_mass[v] = m.vert_mass[v] > 0 ? 1.0 / m.vert_mass[v] : 0.0;
    for (int32_t v : od.fixed) {
      const int32_t g = l2g[v];
      if (g >= 0) m.vert_inv_mass[g] = 0.0, r.has_fixed = true;
    }
    if (mat.model == ModelKind::rigid) {  // rigid: every vertex held where the mesh puts it
      std::fill(m.vert_inv_mass.begin() + r.vert_begin, m.vert_inv_mass.begin() + r.vert_end, 0.0);
      r.has_fixed = true;
    }
    m.organs.push_back(r);
  }

  // ---- connections between kept organs ----
  int64_t dropped_conn = 0;
  for (const ConnectionDesc& cd : scene.connections) {
    if (!keep[cd.organ_a] || !keep[cd.organ_b]) {
      ++dropped_conn;
      continue;
    }
    const int32_t a = local_to_global[cd.organ_a][cd.vertex_a];
    const int32_t b = local_to_global[cd.organ_b][cd.vertex_b];
    require(a >= 0 && b >= 0,
            "connection " + scene.organs[cd.organ_a].name + ":" + std::to_string(cd.vertex_a) + " - " +
                scene.organs[cd.organ_b].name + ":" + std::to_string(cd.vertex_b),
            "connects a vertex used by no face");
    if (cd.stiffness == 0) {
      ++dropped_conn;
      continue;
    }
    if (scene.organs[cd.organ_a].material.model == ModelKind::rigid &&
        scene.organs[cd.organ_b].material.model == ModelKind::rigid) {
      ++dropped_conn;
      continue;
    }
    m.conn_a.push_back(a), m.conn_b.push_back(b);
    m.conn_rest.push_back(cd.rest_length_m);
    m.conn_k.push_back(cd.stiffness);
    m.conn_d.push_back(spring_damping(cd.stiffness, m.vert_mass[a], m.vert_mass[b]));
    ++m.nconn;
    for (int32_t v : {a, b})
      if (m.organs[m.vert_organ[v]].model == ModelKind::rigid) m.rigid_conn_verts.push_back(v);
  }
  std::sort(m.rigid_conn_verts.begin(), m.rigid_conn_verts.end());
  m.rigid_conn_verts.erase(std::unique(m.rigid_conn_verts.begin(), m.rigid_conn_verts.end()), m.rigid_conn_verts.end());
  if (dropped_conn)
    m.dropped.push_back(std::to_string(dropped_conn) +
                        " connection springs: to organs left out, zero stiffness, or between two rigid organs");

  // organ adjacency (CSR) for sleeping and waking
  const int32_t norg = static_cast<int32_t>(m.organs.size());
  std::vector<std::vector<int32_t>> cadj(norg);
  for (int32_t s = 0; s < m.nconn; ++s) {
    const int32_t oa = m.vert_organ[m.conn_a[s]], ob = m.vert_organ[m.conn_b[s]];
    if (oa != ob) cadj[oa].push_back(ob), cadj[ob].push_back(oa);
  }
  m.organ_neighbors_begin.push_back(0);
  for (auto& list : cadj) {
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
    m.organ_neighbors.insert(m.organ_neighbors.end(), list.begin(), list.end());
    m.organ_neighbors_begin.push_back(static_cast<int32_t>(m.organ_neighbors.size()));
  }
  // connected components of organs; connections sorted by component
  {
    std::vector<int32_t> comp(norg, -1);
    int32_t ncomp = 0;
    m.component_begin.push_back(0);
    for (int32_t o = 0; o < norg; ++o) {
      if (comp[o] >= 0) continue;
      std::vector<int32_t> stack{o};
      comp[o] = ncomp;
      while (!stack.empty()) {
        const int32_t u = stack.back();
        stack.pop_back();
        m.component_organs.push_back(u);
        for (int32_t nb : cadj[u])
          if (comp[nb] < 0) comp[nb] = ncomp, stack.push_back(nb);
      }
      ++ncomp;
      m.component_begin.push_back(static_cast<int32_t>(m.component_organs.size()));
    }
    std::vector<int32_t> order(m.nconn);
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](int32_t a, int32_t b) {
      return comp[m.vert_organ[m.conn_a[a]]] < comp[m.vert_organ[m.conn_a[b]]];
    });
    auto permute = [&](auto& v) {
      auto copy = v;
      for (int32_t i = 0; i < m.nconn; ++i) v[i] = copy[order[i]];
    };
    permute(m.conn_a), permute(m.conn_b), permute(m.conn_rest), permute(m.conn_k), permute(m.conn_d);
    m.component_conn_begin.assign(ncomp + 1, 0);
    for (int32_t i = 0; i < m.nconn; ++i) ++m.component_conn_begin[comp[m.vert_organ[m.conn_a[i]]] + 1];
    for (int32_t c = 0; c < ncomp; ++c) m.component_conn_begin[c + 1] += m.component_conn_begin[c];
  }
  m.size_m = std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                       (hi[2] - lo[2]) * (hi[2] - lo[2]));
  if (!(m.size_m > 0)) m.size_m = 1.0;

  // ---- stability estimate and the guard's plan ----
  m.stable_dt_s = estimate_stable_dt(m, k_eff);
  m.effective_integrator = m.integrator;
  m.substeps = 1;
  if (m.integrator != Integrator::implicit && m.guard && std::isfinite(m.stable_dt_s) && m.dt_s > 0.9 * m.stable_dt_s) {
    const double need = std::ceil(m.dt_s / (0.9 * m.stable_dt_s));
    if (need <= m.max_substeps) {
      m.substeps = static_cast<int>(need);
    } else {
      m.effective_integrator = Integrator::implicit;
    }
  }

  compile_solids(scene, m);           // lattices of the solid organs (solid_step.cpp)
  compile_contact(scene.contact, m);  // contact between organs (contact.cpp)

  // ---- the plan, in words ----
  std::ostringstream os;
  auto line = [&](const std::string& s) { m.plan.push_back(s); };
  int64_t nfix = 0;
  for (double w : m.vert_inv_mass) nfix += (w == 0.0);
  os << m.organs.size() << " organs, " << m.nvert << " vertices (" << nfix << " fixed), " << m.nface << " faces, "
     << m.nspring << " springs, " << m.nconn << " connection springs, " << m.nflex << " flexion springs";
  line(os.str());
  if (m.contact.on) {
    int64_t inside = 0;
    for (uint8_t f : m.contact.rest_inside) inside += f;
    line("contact between organs: vertices closer than their partners' boxes + " +
         std::to_string(static_cast<int>(std::lround(m.contact.depth_m * 1e3))) +
         " mm projected out of their nearest face (hash grid, " + std::to_string(m.contact.table_size) + " buckets); " +
         std::to_string(inside) + " vertices inside another organ at rest are exempt");
  } else if (scene.contact) {
    m.dropped.push_back("contact: fewer than two organs");
  }
  for (const OrganRange& r : m.organs) {
    std::string s = "organ '" + r.name + "' [" + to_string(r.model) +
                    "]: " + std::to_string(r.spring_end - r.spring_begin) + " springs";
    if (r.elastica_frozen)
      s += ", conservative elastica: Hooke springs of stiffness k (a + b |kappa0 L|^p) at the rest "
           "curvature (b = " +
           num(r.elastica_b) + ", p = " + std::to_string(r.elastica_p) + "), no curvature pass";
    else if (r.model == ModelKind::nmsm)
      s += r.curvature ? ", curvature pass (b = " + num(r.elastica_b) + ", p = " + std::to_string(r.elastica_p) + ")"
                       : ", no curvature pass (b = 0: elastica springs reduce to Hooke)";
    s += r.damping ? ", spring damping" : ", no damping pass (d = 0)";
    if (r.compensation_iterations > 0)
      s += ", compensation (tau_s = " + num(r.tau_s) + ", tau_c = " + num(r.tau_c) + ", " +
           std::to_string(r.compensation_iterations) + " iterations)";
    if (r.flex_end > r.flex_begin) s += ", " + std::to_string(r.flex_end - r.flex_begin) + " flexion springs";
    if (r.volume_stiffness > 0) s += ", volume constraint (stiffness " + num(r.volume_stiffness) + ")";
    if (r.model == ModelKind::rigid)
      s = "organ '" + r.name + "' [rigid]: all " + std::to_string(r.vert_end - r.vert_begin) +
          " vertices fixed, no internal forces, never stepped (anchors connection springs)";
    else if (!r.has_fixed)
      s += ", no fixed vertices";
    if (r.model == ModelKind::solid) s += ", " + solid_plan(m.solids[m.organ_solid[&r - m.organs.data()]]);
    line(s);
  }
  line(m.gravity ? "gravity on" : "no gravity pass (gravity off)");
  line(std::string("integrator ") + to_string(m.integrator) + ", dt = " + num(m.dt_s) + " s");
  if (m.integrator == Integrator::implicit)
    line("implicit Euler: CG up to " + std::to_string(m.cg_iterations) + " iterations, relative tolerance " +
         num(m.cg_tolerance));
  line("stable explicit dt estimate " + num(m.stable_dt_s) + " s (Gershgorin bound)");
  if (m.guard) {
    if (m.effective_integrator != m.integrator)
      line("guard: dt is " + num(m.dt_s / m.stable_dt_s) +
           " x the stable step, more than max_substeps: solving with implicit Euler");
    else if (m.substeps > 1)
      line("guard: " + std::to_string(m.substeps) + " explicit sub-steps per step");
    line("guard: tool force clamped to " + num(m.max_tool_force_N) +
         " N; non-finite or runaway states restored from the last good state");
  } else {
    line("guard off");
  }
  if (capped_springs)
    line(std::to_string(capped_springs) +
         " near-zero-length springs: 000 eq 9 stiffness capped (length floor 1e-3 x median edge)");
  if (degenerate_faces) line(std::to_string(degenerate_faces) + " zero-area faces: no curvature or mass contribution");
  if (m.allow_sleep) line("resting organs sleep until touched");
  return m;
}

std::string explain(const Model& model) {
  std::string out = "compiled plan:\n";
  for (const std::string& s : model.plan) out += "  computes: " + s + "\n";
  for (const std::string& s : model.dropped) out += "  left out: " + s + "\n";
  return out;
}

}  // namespace softatlas::sim
