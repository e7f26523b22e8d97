// `softatlas bench accuracy`: error against run time for every model and setting, measured
// against a FEM reference of the same liver (issue 7): quadratic tetrahedra, neo-Hookean, nearly
// incompressible, Newton with the consistent tangent (sim/fem_quadratic.hpp, issue 13).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <type_traits>

#include "softatlas/evidence/evidence.hpp"
#include "softatlas/evidence/svg.hpp"
#include "softatlas/io/mesh_io.hpp"
#include "softatlas/sim/error.hpp"
#include "softatlas/sim/fem_quadratic.hpp"
#include "trajectory.hpp"

namespace softatlas::evidence {

namespace fem = sim::fem;
using nlohmann::json;

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void progress(const char* fmt, const std::string& a, double b = 0.0) {
  std::fprintf(stderr, fmt, a.c_str(), b);
  std::fflush(stderr);
}

std::vector<int32_t> nodes_where(const fem::TetMesh& mesh, int axis, double value) {
  std::vector<int32_t> out;
  for (int32_t i = 0; i < mesh.nnode(); ++i)
    if (std::abs(mesh.nodes[3 * i + axis] - value) < 1e-12) out.push_back(i);
  return out;
}

// Consistent nodal forces of a uniform traction on the boundary faces in the plane axis = value.
void add_traction(const fem::TetMesh& mesh, fem::Load& load, int axis, double value, const std::array<double, 3>& t) {
  const std::vector<int32_t> faces = fem::boundary_faces(mesh);
  for (size_t f = 0; f < faces.size() / 3; ++f) {
    bool on = true;
    for (int k = 0; k < 3; ++k) on = on && std::abs(mesh.nodes[3 * faces[3 * f + k] + axis] - value) < 1e-12;
    if (!on) continue;
    const double* a = &mesh.nodes[3 * faces[3 * f]];
    const double* b = &mesh.nodes[3 * faces[3 * f + 1]];
    const double* c = &mesh.nodes[3 * faces[3 * f + 2]];
    const double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    const double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2],
                 cz = e1[0] * e2[1] - e1[1] * e2[0];
    const double area = 0.5 * std::sqrt(cx * cx + cy * cy + cz * cz);
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 3; ++d) load.force[3 * faces[3 * f + k] + d] += t[d] * area / 3.0;
  }
}

std::vector<int32_t> fem_support(const fem::TetMesh& mesh) { return support_vertices(mesh.nodes, kSupportFraction); }

// Surface nodes of the tet mesh within the tool radius.
std::vector<int32_t> fem_tool_nodes(const fem::TetMesh& mesh, const std::array<double, 3>& top) {
  const std::vector<int32_t> faces = fem::boundary_faces(mesh);
  std::vector<uint8_t> on(mesh.nnode(), 0);
  for (int32_t n : faces) on[n] = 1;
  std::vector<int32_t> out;
  int32_t best = -1;
  double bd = INFINITY;
  for (int32_t i = 0; i < mesh.nnode(); ++i) {
    if (!on[i]) continue;
    double d2 = 0;
    for (int c = 0; c < 3; ++c) d2 += (mesh.nodes[3 * i + c] - top[c]) * (mesh.nodes[3 * i + c] - top[c]);
    if (d2 <= kToolRadius * kToolRadius) out.push_back(i);
    if (d2 < bd) bd = d2, best = i;
  }
  if (out.empty()) out.push_back(best);
  return out;
}

struct FemSolution {
  std::vector<double> x;
  std::array<double, 3> reaction{0, 0, 0};
  double seconds = 0.0;
  int iterations = 0;
  double residual = 0.0;
  bool converged = false;
  std::vector<PathPoint> path;  // the state after each load increment (the last is x)
};

// The nodes of a region given by its corners: the corners themselves for linear tetrahedra,
// with the edge nodes between them for quadratic ones.
std::vector<int32_t> region_nodes(const fem::Model&, const std::vector<int32_t>& corners) { return corners; }
std::vector<int32_t> region_nodes(const fem::QuadraticModel& q, const std::vector<int32_t>& corners) {
  return fem::quadratic_region(q, corners);
}

// A static solve of the liver (the reference, or a coarse linear FEM as a model): support and
// tool region as the surface models have them, a force spread over the tool region's nodes.
// Linear corotational: 10 load increments for attachments (the approximate-tangent Newton, no
// derivative of R, stays in its convergence basin), tolerance 1e-6. Quadratic: increments of at
// most 5 mm, tolerance 1e-9 (Newton with the consistent tangent).
template <class FemModel>
FemSolution solve_reference(const FemModel& model, const fem::TetMesh& mesh, const LoadCase& load,
                            const std::array<double, 3>& top) {
  constexpr bool quadratic = std::is_same_v<FemModel, fem::QuadraticModel>;
  FemSolution s;
  fem::Load l = fem::make_load(model);
  fem::fix_nodes(l, region_nodes(model, fem_support(mesh)), {0, 0, 0});
  const std::vector<int32_t> tool = region_nodes(model, fem_tool_nodes(mesh, top));
  if (load.attach)
    fem::fix_nodes(l, tool, load.value);
  else
    fem::add_force(l, tool, load.value);
  s.x = model.rest;
  fem::StaticOptions opt;
  if (quadratic) {
    opt.load_steps = load.attach ? std::max(1, static_cast<int>(std::ceil(norm3(load.value) / 0.005))) : 1;
    opt.max_iterations = 30;
    opt.tolerance = 1e-9;
  } else {
    opt.load_steps = load.attach ? 10 : 1;
    opt.max_iterations = 100;
    opt.tolerance = 1e-6;
  }
  opt.on_increment = [&s](double fraction, const std::vector<double>& x) { s.path.push_back({fraction, x}); };
  const auto t0 = std::chrono::steady_clock::now();
  const fem::StaticReport rep = fem::solve_static(model, l, s.x, opt);
  s.seconds = seconds_since(t0);
  s.iterations = rep.iterations;
  s.converged = rep.converged;
  s.residual = rep.residual;
  s.reaction = fem::reaction_force(model, s.x, tool);
  return s;
}

// What a tool feels per metre of its displacement: |reaction| / |displacement|.
double grasp_stiffness(const std::array<double, 3>& reaction, const std::array<double, 3>& displacement) {
  return norm3(reaction) / std::max(norm3(displacement), 1e-300);
}

// Attachments only: force error against the reference and grasp stiffness (see Snapshot).
void add_force_metrics(json& run, const Snapshot& s) {
  if (!std::isfinite(s.grasp_stiffness_N_per_m)) return;
  run["grasp_stiffness_N_per_m"] = s.grasp_stiffness_N_per_m;
  if (std::isfinite(s.force_error_pct)) run["force_error_pct"] = s.force_error_pct;
  if (std::isfinite(s.grasp_stiffness_ratio)) run["grasp_stiffness_ratio"] = s.grasp_stiffness_ratio;
}

std::vector<int> face_counts(Grid g) {
  if (g == Grid::tiny) return {600};
  if (g == Grid::quick) return {1000, 2000};
  return {1000, 2000, 4000, 10000};  // 6000 and 8000 left out: the full run must fit in 30 min
}

struct Combo {
  std::string model, integrator;
  double dt_s = 1e-3;  // 1 kHz, the haptic rate; the solid model also at its own step (8 ms)
};
std::vector<Combo> combos(Grid g) {
  std::vector<Combo> out;
  const std::vector<std::string> msm = g == Grid::tiny
                                           ? std::vector<std::string>{"tmsm", "nmsm"}
                                           : std::vector<std::string>{"tmsm", "cmsm", "nmsm", "nmsm_p2", "flexion"};
  const std::vector<std::string> integ = g == Grid::tiny
                                             ? std::vector<std::string>{"semi_implicit", "implicit"}
                                             : std::vector<std::string>{"verlet", "semi_implicit", "implicit"};
  for (const auto& m : msm)
    for (const auto& i : integ) out.push_back({m, i});
  out.push_back({"tmm", "implicit"});
  out.push_back({"solid", "implicit"});        // the atlas default (sim/solid.hpp): its own local/global solver
  out.push_back({"solid", "implicit", 8e-3});  // ... at the step the atlas runs it with (kSolidStep_s)
  return out;
}

// Pareto front (minimise both): indices of non-dominated points, sorted by x.
std::vector<size_t> pareto(const std::vector<double>& x, const std::vector<double>& y) {
  std::vector<size_t> idx;
  for (size_t i = 0; i < x.size(); ++i)
    if (std::isfinite(x[i]) && std::isfinite(y[i]) && x[i] > 0 && y[i] > 0) idx.push_back(i);
  std::sort(idx.begin(), idx.end(), [&](size_t a, size_t b) { return x[a] < x[b] || (x[a] == x[b] && y[a] < y[b]); });
  std::vector<size_t> front;
  double best = INFINITY;
  for (size_t i : idx)
    if (y[i] < best) {
      front.push_back(i);
      best = y[i];
    }
  return front;
}

const std::map<std::string, int>& model_colors() {
  static const std::map<std::string, int> c = {{"tmsm", 0},    {"cmsm", 1}, {"nmsm", 2}, {"nmsm_p2", 3},
                                               {"flexion", 4}, {"tmm", 5},  {"fem", 6},  {"solid", 7}};
  return c;
}
std::string integrator_marker(const std::string& i) {
  if (i == "verlet") return "triangle";
  if (i == "semi_implicit") return "circle";
  if (i == "implicit") return "square";
  return "diamond";
}

// One scatter plot of a run metric against ms per step, one series per model x integrator, the
// Pareto front of the whole cloud drawn as a dashed line; for a ratio to the reference (`ratio`:
// 1 is right, neither direction is better) the line y = 1 instead.
std::string metric_plot(const json& runs, const std::string& metric, const std::string& label, const std::string& title,
                        const std::string& load_filter, bool logy, bool ratio = false) {
  svg::Plot p;
  p.title = title;
  p.xlabel = "ms per step (log)";
  p.ylabel = label;
  p.logx = true;
  p.logy = logy;
  std::map<std::string, svg::Series> series;
  std::vector<double> ax, ay;
  for (const auto& r : runs) {
    if (!load_filter.empty() && r["load"] != load_filter) continue;
    if (!r.contains(metric) || !r[metric].is_number()) continue;
    const std::string key = r["model"].get<std::string>() + " / " + integrator_label(r);
    auto& s = series[key];
    if (s.name.empty()) {
      s.name = key;
      s.color = svg::color(model_colors().count(r["model"]) ? model_colors().at(r["model"]) : 9);
      s.marker = integrator_marker(r["integrator"]);
    }
    const double y = std::abs(r[metric].get<double>());
    s.x.push_back(r["ms_per_step"].get<double>());
    s.y.push_back(y);
    ax.push_back(r["ms_per_step"].get<double>());
    ay.push_back(y);
  }
  for (auto& kv : series) p.series.push_back(kv.second);
  svg::Series front;
  front.name = ratio ? "reference (1)" : "Pareto front";
  front.color = "#222222";
  front.marker = "none";
  front.line = true;
  front.dashed = true;
  if (ratio && !ax.empty()) {
    front.x = {*std::min_element(ax.begin(), ax.end()), *std::max_element(ax.begin(), ax.end())};
    front.y = {1.0, 1.0};
  } else if (!ratio) {
    for (size_t i : pareto(ax, ay)) {
      front.x.push_back(ax[i]);
      front.y.push_back(ay[i]);
    }
  }
  p.series.push_back(front);
  return svg::render(p);
}

}  // namespace

void write_file_atomic(const std::string& path, const std::string& content) {
  io::write_file_atomic(path, content);  // the project's one atomic writer
}

TriMesh load_liver(const std::string& data_dir) {
  const std::string path = data_dir + "/meshes/sofa/liver-smooth.obj";
  if (!std::filesystem::exists(path))
    throw InputError(path, "missing (expected the shared data folder; pass --data DIR)");
  return normalise_organ(read_surface(path), 0.17);
}

json fem_verification(Grid grid) {
  json out = json::array();
  {
    // Compressed block under a uniform pressure with symmetry-plane supports: uniaxial stress,
    // u_z(top) = -p H / E exactly for linear tetrahedra.
    const double lx = 0.02, ly = 0.02, lz = 0.04, E = 4000.0, nu = 0.45, p = 50.0;
    const fem::TetMesh mesh = fem::box_mesh(lx, ly, lz, 2, 2, 4);
    fem::Material mat;
    mat.young_modulus_pa = E;
    mat.poisson_ratio = nu;
    mat.elasticity = fem::Elasticity::linear;
    const fem::Model model = fem::compile(mesh, mat);
    fem::Load load = fem::make_load(model);
    for (int axis = 0; axis < 3; ++axis)
      for (int32_t i : nodes_where(mesh, axis, 0.0)) load.dof_fixed[3 * i + axis] = 1;
    add_traction(mesh, load, 2, lz, {0, 0, -p});
    std::vector<double> x = model.rest;
    fem::solve_static(model, load, x);
    const std::vector<int32_t> top = nodes_where(mesh, 2, lz);
    double uz = 0;
    for (int32_t i : top) uz += x[3 * i + 2] - model.rest[3 * i + 2];
    uz /= static_cast<double>(top.size());
    const double analytic = -p * lz / E;
    out.push_back({{"case", "compressed_block_linear"},
                   {"quantity", "top displacement u_z (m)"},
                   {"analytic", analytic},
                   {"computed", uz},
                   {"rel_error", std::abs(uz - analytic) / std::abs(analytic)},
                   {"tets", mesh.ntet()}});
  }
  // Cantilever (L/h = 10) under a tip shear load: Timoshenko tip deflection; linear tetrahedra
  // lock in bending, so the error falls with refinement (convergence under refinement).
  const int nmax = grid == Grid::full ? 5 : grid == Grid::quick ? 3 : 2;
  for (int pass = 0; pass < 2; ++pass) {
    const bool corot = pass == 1;
    for (int n = corot ? nmax : 1; n <= nmax; ++n) {
      const double L = 0.1, h = 0.01, E = 1e5, nu = 0.3, P = corot ? 1e-4 : 1e-3;
      const fem::TetMesh mesh = fem::box_mesh(L, h, h, 10 * n, n, n);
      fem::Material mat;
      mat.young_modulus_pa = E;
      mat.poisson_ratio = nu;
      mat.elasticity = corot ? fem::Elasticity::corotational : fem::Elasticity::linear;
      const fem::Model model = fem::compile(mesh, mat);
      fem::Load load = fem::make_load(model);
      fem::fix_nodes(load, nodes_where(mesh, 0, 0.0), {0, 0, 0});
      add_traction(mesh, load, 0, L, {0, 0, -P / (h * h)});
      std::vector<double> x = model.rest;
      fem::solve_static(model, load, x);
      const std::vector<int32_t> tip = nodes_where(mesh, 0, L);
      double uz = 0;
      for (int32_t i : tip) uz += x[3 * i + 2] - model.rest[3 * i + 2];
      uz = -uz / static_cast<double>(tip.size());
      const double I = h * h * h * h / 12.0, G = E / (2 * (1 + nu));
      const double analytic = P * L * L * L / (3 * E * I) + P * L / (5.0 / 6.0 * G * h * h);
      out.push_back(
          {{"case", std::string("cantilever_") + (corot ? "corotational" : "linear") + "_n" + std::to_string(n)},
           {"quantity", "tip deflection (m), Timoshenko beam"},
           {"analytic", analytic},
           {"computed", uz},
           {"rel_error", std::abs(uz - analytic) / analytic},
           {"tets", mesh.ntet()},
           {"cells_through_thickness", n}});
    }
  }
  // The reference's element: quadratic tetrahedra, neo-Hookean, nearly incompressible. The
  // clamp as beam theory has it (plane section, free to contract: u_x = 0 on the end face, u_z and
  // u_y held on its neutral lines), consistent tip traction on the 6-node faces.
  for (double nu : {0.3, 0.49}) {
    for (int n = 1; n <= (grid == Grid::tiny ? 1 : 2); ++n) {
      const double L = 0.1, h = 0.01, E = 1e5, P = 1e-4;
      const fem::TetMesh mesh = fem::box_mesh(L, h, h, 10 * n, n, n);
      fem::Material mat;
      mat.young_modulus_pa = E;
      mat.poisson_ratio = nu;
      const fem::QuadraticModel q = fem::compile_quadratic(mesh, mat);
      fem::Load load = fem::make_load(q);
      for (int32_t i = 0; i < q.nnode; ++i) {
        if (std::abs(q.rest[3 * i]) > 1e-12) continue;
        load.dof_fixed[3 * i] = 1;
        if (std::abs(q.rest[3 * i + 1] - h / 2) < 1e-12) load.dof_fixed[3 * i + 1] = 1;
        if (std::abs(q.rest[3 * i + 2] - h / 2) < 1e-12) load.dof_fixed[3 * i + 2] = 1;
      }
      std::vector<int32_t> tip_faces;
      const std::vector<int32_t> all = fem::boundary_faces(mesh);
      for (size_t f = 0; f + 2 < all.size(); f += 3)
        if (std::abs(mesh.nodes[3 * all[f]] - L) < 1e-12 && std::abs(mesh.nodes[3 * all[f + 1]] - L) < 1e-12 &&
            std::abs(mesh.nodes[3 * all[f + 2]] - L) < 1e-12)
          tip_faces.insert(tip_faces.end(), {all[f], all[f + 1], all[f + 2]});
      fem::add_traction(q, load, tip_faces, {0, 0, -P / (h * h)});
      std::vector<double> x = q.rest;
      const fem::StaticReport rep = fem::solve_static(q, load, x);
      double uz = 0;
      int ntip = 0;
      for (int32_t i = 0; i < q.nnode; ++i)
        if (std::abs(q.rest[3 * i] - L) < 1e-12) uz += x[3 * i + 2] - q.rest[3 * i + 2], ++ntip;
      uz = -uz / ntip;
      const double I = h * h * h * h / 12.0, G = E / (2 * (1 + nu));
      const double analytic = P * L * L * L / (3 * E * I) + P * L / (5.0 / 6.0 * G * h * h);
      char name[64];
      std::snprintf(name, sizeof name, "cantilever_quadratic_nu%.2f_n%d", nu, n);
      out.push_back({{"case", name},
                     {"quantity", "tip deflection (m), Timoshenko beam"},
                     {"analytic", analytic},
                     {"computed", uz},
                     {"rel_error", std::abs(uz - analytic) / analytic},
                     {"tets", mesh.ntet()},
                     {"cells_through_thickness", n},
                     {"converged", rep.converged},
                     {"newton_iterations", rep.iterations}});
    }
  }
  return out;
}

json run_accuracy(const Options& opt) {
  const auto t_start = std::chrono::steady_clock::now();
  json result;
  result["command"] = "bench accuracy";
  result["grid"] = opt.grid == Grid::full ? "full" : opt.grid == Grid::quick ? "quick" : "tiny";
  progress("accuracy: FEM verification%s\n", "");
  result["fem_verification"] = fem_verification(opt.grid);

  // ---- the liver, its FEM reference and its surfaces ----
  const TriMesh source = load_liver(opt.data_dir);
  const std::array<double, 3> top = top_point(source);
  const double cell = opt.grid == Grid::full ? 0.009 : opt.grid == Grid::quick ? 0.014 : 0.02;
  progress("accuracy: tetrahedralising the liver (cell %s%.3f m)\n", "", cell);
  // Refined around the tool: the edge of its held patch is a stress singularity, and at one cell
  // size everywhere the patch's held area itself changed with the mesh (the full grid's reaction
  // changed by 8.9 % under refinement, the quick grid's attach_20 reference was 11 % softer).
  // Half the cell size there: on the quick grid the reaction then changes by 0.17 % under
  // refinement (a third: 1.2 %, and the full grid's fine solve took over 40 minutes).
  auto tool_focus = [&](double c) { return RefineFocus{top, 1.5 * kToolRadius, c / 2.0, 0.5}; };
  const RefineFocus focus = tool_focus(cell);
  const fem::TetMesh tets = tetrahedralize(source, cell, 0.001, &focus);
  // The material of every model and of the reference: E = 4 kPa, nearly incompressible.
  fem::Material fmat;
  fmat.young_modulus_pa = 4000.0;
  fmat.poisson_ratio = 0.49;
  fmat.elasticity = fem::Elasticity::corotational;  // the FEM-as-a-model rows (linear tetrahedra)
  const fem::QuadraticModel fmodel = fem::compile_quadratic(tets, fmat);
  json ref_info = {
      {"model", "fem quadratic tetrahedra, neo-Hookean, static (Newton, consistent tangent, line search)"},
      {"nodes", fmodel.nnode},
      {"corner_nodes", fmodel.nvertex},
      {"tets", fmodel.ntet},
      {"young_modulus_pa", fmat.young_modulus_pa},
      {"poisson_ratio", fmat.poisson_ratio},
      {"cell_size_m", cell},
      {"support", "nodes in the lowest 15% of the height (y) held"},
      {"tool", "surface nodes within 12 mm of the top vertex"},
      {"tool_refinement", "cells of half the cell size within 18 mm of the tool, growing 0.5 m per m beyond"},
      {"solutions", json::array()}};
  const std::vector<LoadCase> loads =
      opt.grid == Grid::tiny ? std::vector<LoadCase>{accuracy_loads(true)[1]} : accuracy_loads(opt.grid == Grid::quick);
  std::vector<FemSolution> fem_ref;
  for (const LoadCase& load : loads) {
    progress("accuracy: FEM reference, load %s\n", load.name);
    fem_ref.push_back(solve_reference(fmodel, tets, load, top));
    const FemSolution& s = fem_ref.back();
    json sol = {{"load", load.name},
                {"seconds", s.seconds},
                {"newton_iterations", s.iterations},
                {"converged", s.converged},
                {"relative_residual", s.residual},
                {"reaction_N", s.reaction}};
    if (load.attach) sol["grasp_stiffness_N_per_m"] = grasp_stiffness(s.reaction, load.value);
    ref_info["solutions"].push_back(sol);
  }
  // Is the reference converged in the mesh? The largest attachment solved again on a finer
  // mesh; the change of the surface displacement (RMS and max over the liver's own vertices).
  if (opt.grid != Grid::tiny) {
    const double fine_cell = cell * 0.75;
    size_t li = 0;
    for (size_t i = 0; i < loads.size(); ++i)
      if (loads[i].attach && norm3(loads[i].value) >= norm3(loads[li].value)) li = i;
    progress("accuracy: FEM reference refinement (cell %s%.4f m)\n", "", fine_cell);
    const RefineFocus fine_focus = tool_focus(fine_cell);
    const fem::TetMesh fine_tets = tetrahedralize(source, fine_cell, 0.001, &fine_focus);
    const fem::QuadraticModel fine = fem::compile_quadratic(fine_tets, fmat);
    const FemSolution fs = solve_reference(fine, fine_tets, loads[li], top);
    std::vector<double> d0, d1;
    fem::interpolate(fmodel, fem::embed_points(fmodel.linear, source.V), fem_ref[li].x, d0);
    fem::interpolate(fine, fem::embed_points(fine.linear, source.V), fs.x, d1);
    std::vector<double> moved = source.V;
    for (size_t k = 0; k < moved.size(); ++k) moved[k] += d1[k];
    double rms = 0, mx = 0;
    position_error_mm(source.V, moved, d0, rms, mx);
    ref_info["refinement"] = {
        {"load", loads[li].name},
        {"cell_size_m", fine_cell},
        {"tets", fine.ntet},
        {"nodes", fine.nnode},
        {"converged", fs.converged},
        {"seconds", fs.seconds},
        {"rms_change_mm", rms},
        {"max_change_mm", mx},
        {"reaction_change_pct", 100.0 * std::abs(norm3(fs.reaction) - norm3(fem_ref[li].reaction)) /
                                    std::max(norm3(fem_ref[li].reaction), 1e-300)}};
    std::fprintf(stderr, "  refinement %s: rms change %.3f mm, max %.3f mm\n", loads[li].name.c_str(), rms, mx);
  }
  result["reference"] = ref_info;

  // FEM convergence under refinement on the liver itself: the tool displacement under the
  // first force load with coarser meshes against this reference.
  json runs = json::array();
  const std::vector<int> faces = face_counts(opt.grid);
  const std::vector<int64_t> snap_steps =
      opt.grid == Grid::full ? std::vector<int64_t>{30, 300} : std::vector<int64_t>{30, 300};
  const int64_t max_steps = opt.grid == Grid::full ? 2000 : opt.grid == Grid::quick ? 1500 : 400;
  const double accel_tol = 1e-6;  // paper 000: sum |a| < 1e-6
  const double dt = 1e-3;         // 1 kHz: the haptic rate
  for (int nf : faces) {
    const TriMesh surface = remesh_to_faces(source, nf);
    const std::vector<int32_t> fixed = support_vertices(surface.V, kSupportFraction);
    const std::vector<int32_t> tool = region(surface.V, top, kToolRadius);
    const fem::Embedding emb = fem::embed_points(fmodel.linear, surface.V);
    for (size_t li = 0; li < loads.size(); ++li) {
      const LoadCase& load = loads[li];
      // Above 2000 faces the full grid keeps the two large attachment loads (time budget: < 30 min).
      if (opt.grid == Grid::full && nf > 2000 && load.name != "attach_30" && load.name != "pull_50mm") continue;
      Reference ref;
      fem::interpolate(fmodel, emb, fem_ref[li].x, ref.disp);
      ref.reaction = fem_ref[li].reaction;
      ref.valid = true;
      const bool restoration = load.name == "attach_30" || (opt.grid != Grid::full && load.attach);
      for (const Combo& c : combos(opt.grid)) {
        // Verlet (Algorithm 1) is algebraically the semi-implicit step; above 2000 faces the full
        // grid runs it once (as semi_implicit) to save time.
        if (opt.grid == Grid::full && nf > 2000 && c.integrator == "verlet") continue;
        ModelSpec spec = paper_spec(c.model, c.integrator, nf);
        spec.dt_s = c.dt_s;
        std::unique_ptr<Simulation> sim;
        try {
          sim = make_surface_simulation(surface, fixed, spec);
        } catch (const InputError& e) {
          std::fprintf(stderr, "accuracy: %s/%s at %d faces rejected: %s\n", c.model.c_str(), c.integrator.c_str(), nf,
                       e.what());
          continue;
        }
        const Trajectory tr =
            run_trajectory(*sim, surface, tool, load, ref, c.dt_s, snap_steps, max_steps, accel_tol, restoration);
        for (size_t k = 0; k < tr.snaps.size(); ++k) {
          const Snapshot& s = tr.snaps[k];
          json r = {{"model", c.model},
                    {"integrator", c.integrator},
                    {"faces", surface.nface()},
                    {"vertices", surface.nvert()},
                    {"load", load.name},
                    {"dt_s", c.dt_s},
                    {"iterations", s.iterations},
                    {"converged", s.converged},
                    {"final", k + 1 == tr.snaps.size()},
                    {"ms_per_step", s.ms_per_step},
                    {"rms_error_mm", s.rms_mm},
                    {"max_error_mm", s.max_mm},
                    {"volume_change_pct", s.volume_change_pct},
                    {"reaction_N", s.reaction},
                    {"finite", s.finite},
                    {"guard_actions", s.guard_actions},
                    {"stable_dt_s", sim->stable_dt()}};
          add_force_metrics(r, s);
          if (c.model == "nmsm" || c.model == "nmsm_p2") r["elastica_b"] = spec.elastica_b;
          if (k + 1 == tr.snaps.size() && tr.restored_measured) {
            r["restoration_mean_mm"] = tr.restoration_mean_mm;
            r["restoration_sd_mm"] = tr.restoration_sd_mm;
            r["restoration_time_ms"] = tr.restoration_time_ms;
          }
          runs.push_back(r);
        }
        const Snapshot& last = tr.snaps.back();
        std::fprintf(
            stderr,
            "  %5d faces %-10s %-8s %-14s dt %g ms  it %6lld  %.4f ms/step  rms %.3f mm  vol %+.2f%%  force %.1f%%\n",
            nf, load.name.c_str(), c.model.c_str(), c.integrator.c_str(), 1e3 * c.dt_s,
            static_cast<long long>(last.iterations), last.ms_per_step, last.rms_mm, last.volume_change_pct,
            last.force_error_pct);
      }
    }
  }
  // The FEM as a model: implicit dynamics on coarser tetrahedra of the same liver, measured on
  // its boundary against the fine reference; and the static solve itself.
  {
    const std::vector<double> cells = opt.grid == Grid::full
                                          ? std::vector<double>{0.028, 0.018}
                                          : std::vector<double>{opt.grid == Grid::tiny ? 0.035 : 0.028};
    for (double cs : cells) {
      const fem::TetMesh coarse = tetrahedralize(source, cs, 0.002);
      for (size_t li = 0; li < loads.size(); ++li) {
        const LoadCase& load = loads[li];
        ModelSpec spec = paper_spec("fem", "implicit", 0);
        spec.dt_s = dt;
        spec.rayleigh_mass = 5.0;
        spec.rayleigh_stiffness = 0.01;
        TriMesh boundary;
        std::vector<int32_t> bnodes;
        auto sim = make_fem_simulation(coarse, fem_support(coarse), spec, boundary, bnodes);
        const fem::Embedding emb = fem::embed_points(fmodel.linear, boundary.V);
        Reference ref;
        fem::interpolate(fmodel, emb, fem_ref[li].x, ref.disp);
        ref.reaction = fem_ref[li].reaction;
        ref.valid = true;
        const std::vector<int32_t> tool = region(boundary.V, top, kToolRadius);
        const int64_t fem_steps = opt.grid == Grid::full ? 300 : 100;
        const Trajectory tr = run_trajectory(*sim, boundary, tool, load, ref, dt, {30}, fem_steps, accel_tol, false);
        for (const Snapshot& s : tr.snaps) {
          json r = {{"model", "fem"},
                    {"integrator", "implicit"},
                    {"faces", boundary.nface()},
                    {"vertices", boundary.nvert()},
                    {"tets", coarse.ntet()},
                    {"load", load.name},
                    {"dt_s", dt},
                    {"iterations", s.iterations},
                    {"converged", s.converged},
                    {"final", &s == &tr.snaps.back()},
                    {"ms_per_step", s.ms_per_step},
                    {"rms_error_mm", s.rms_mm},
                    {"max_error_mm", s.max_mm},
                    {"volume_change_pct", s.volume_change_pct},
                    {"reaction_N", s.reaction},
                    {"finite", s.finite},
                    {"guard_actions", 0}};
          add_force_metrics(r, s);
          runs.push_back(r);
        }
        // Static solve on the coarse mesh: one "step" is the whole equilibrium solve.
        const fem::Model cmodel = fem::compile(coarse, fmat);
        const FemSolution cs_sol = solve_reference(cmodel, coarse, load, top);
        std::vector<double> bx(boundary.V.size());
        for (size_t i = 0; i < bnodes.size(); ++i)
          for (int c = 0; c < 3; ++c) bx[3 * i + c] = cs_sol.x[3 * bnodes[i] + c];
        double rms = 0, mx = 0;
        position_error_mm(boundary.V, bx, ref.disp, rms, mx);
        Snapshot ss;  // the force metrics of a static solution, as for a run
        ss.reaction = cs_sol.reaction;
        if (load.attach) {
          const std::array<double, 3> d = {cs_sol.reaction[0] - ref.reaction[0], cs_sol.reaction[1] - ref.reaction[1],
                                           cs_sol.reaction[2] - ref.reaction[2]};
          ss.force_error_pct = 100.0 * norm3(d) / std::max(norm3(ref.reaction), 1e-300);
          ss.grasp_stiffness_N_per_m = norm3(cs_sol.reaction) / norm3(load.value);
          ss.grasp_stiffness_ratio = norm3(cs_sol.reaction) / std::max(norm3(ref.reaction), 1e-300);
        }
        const double v0 = fem::mesh_volume(coarse, coarse.nodes), v1 = fem::mesh_volume(coarse, cs_sol.x);
        json r = {{"model", "fem"},
                  {"integrator", "static"},
                  {"faces", boundary.nface()},
                  {"vertices", boundary.nvert()},
                  {"tets", coarse.ntet()},
                  {"load", load.name},
                  {"dt_s", 0.0},
                  {"iterations", cs_sol.iterations},
                  {"converged", cs_sol.converged},
                  {"final", true},
                  {"ms_per_step", 1e3 * cs_sol.seconds},
                  {"rms_error_mm", rms},
                  {"max_error_mm", mx},
                  {"volume_change_pct", 100.0 * (v1 - v0) / v0},
                  {"reaction_N", cs_sol.reaction},
                  {"finite", true},
                  {"guard_actions", 0}};
        add_force_metrics(r, ss);
        runs.push_back(r);
        std::fprintf(stderr, "  fem %d tets %-10s static %.1f ms rms %.3f mm\n", coarse.ntet(), load.name.c_str(),
                     1e3 * cs_sol.seconds, rms);
      }
    }
  }
  // Pareto flags per load, on (ms_per_step, rms_error_mm).
  std::map<std::string, std::vector<size_t>> by_load;
  for (size_t i = 0; i < runs.size(); ++i) by_load[runs[i]["load"]].push_back(i);
  for (auto& kv : by_load) {
    std::vector<double> x, y;
    for (size_t i : kv.second) {
      x.push_back(runs[i]["ms_per_step"].get<double>());
      y.push_back(runs[i]["rms_error_mm"].get<double>());
    }
    for (size_t i : kv.second) runs[i]["pareto"] = false;
    for (size_t j : pareto(x, y)) runs[kv.second[j]]["pareto"] = true;
  }
  result["runs"] = runs;

  if (opt.fit && opt.grid != Grid::tiny) {
    std::vector<std::vector<double>> rx;
    size_t train = 0;  // paper 000 Table II's attachment; its quasi-static path is the training data
    for (size_t i = 0; i < loads.size(); ++i) {
      rx.push_back(fem_ref[i].x);
      if (loads[i].name == "attach_20") train = i;
    }
    result["fitting"] = fit_parameters(opt, source, fmodel, loads, rx, train, fem_ref[train].path);
  }
  if (opt.paper_tables && opt.grid != Grid::tiny) result["paper_tables"] = paper_tables(opt, source);

  // ---- plots ----
  const std::string main_load = opt.grid == Grid::tiny ? loads[0].name : "attach_30";
  // The plots show one attachment (the grasp stiffness exists only there): attach_30 on the full
  // grid, else the first attachment of the grid.
  std::string load_pick = loads[0].name;
  for (auto it = loads.rbegin(); it != loads.rend(); ++it)
    if (it->attach || it->name == main_load) load_pick = it->name;
  if (std::any_of(loads.begin(), loads.end(), [&](const LoadCase& l) { return l.name == main_load; }))
    load_pick = main_load;
  std::vector<std::string> plots;
  auto plot = [&](const std::string& file, const std::string& metric, const std::string& label,
                  const std::string& title, const std::string& load, bool logy, bool ratio = false) {
    write_file_atomic(opt.out_dir + "/" + file, metric_plot(runs, metric, label, title, load, logy, ratio));
    plots.push_back(file);
  };
  plot("rms_error_vs_time.svg", "rms_error_mm", "RMS position error vs FEM (mm, log)",
       "RMS error against run time, load " + load_pick, load_pick, true);
  plot("max_error_vs_time.svg", "max_error_mm", "max position error vs FEM (mm, log)",
       "Max error against run time, load " + load_pick, load_pick, true);
  plot("volume_change_vs_time.svg", "volume_change_pct", "|volume change| (%, log)",
       "Volume change against run time, load " + load_pick, load_pick, true);
  plot("grasp_stiffness_vs_time.svg", "grasp_stiffness_ratio", "grasp stiffness / reference's (log)",
       "Grasp stiffness against run time, load " + load_pick, load_pick, true, true);
  plot("restoration_vs_time.svg", "restoration_mean_mm", "mean restoration error after release (mm, log)",
       "Shape restoration (paper 003 Table 1) against run time", "", true);
  plot("rms_error_vs_time_all_loads.svg", "rms_error_mm", "RMS position error vs FEM (mm, log)",
       "RMS error against run time, all loads", "", true);
  {
    svg::Plot p;
    p.title = "FEM verification: cantilever tip deflection against Timoshenko";
    p.xlabel = "tetrahedra (log)";
    p.ylabel = "relative error vs Timoshenko (log)";
    p.logx = p.logy = true;
    const std::pair<const char*, const char*> kinds[] = {{"linear tetrahedra, nu = 0.3", "cantilever_linear"},
                                                         {"quadratic, nu = 0.3", "cantilever_quadratic_nu0.30"},
                                                         {"quadratic, nu = 0.49", "cantilever_quadratic_nu0.49"}};
    int colour = 0;
    for (const auto& [label, prefix] : kinds) {
      svg::Series s;
      s.name = label;
      s.line = true;
      s.color = svg::color(colour++);
      for (const auto& v : result["fem_verification"])
        if (v["case"].get<std::string>().rfind(prefix, 0) == 0) {
          s.x.push_back(v["tets"].get<double>());
          s.y.push_back(std::max(v["rel_error"].get<double>(), 1e-5));
        }
      p.series.push_back(s);
    }
    write_file_atomic(opt.out_dir + "/fem_convergence.svg", svg::render(p));
    plots.push_back("fem_convergence.svg");
  }
  result["plots"] = plots;
  result["seconds"] = seconds_since(t_start);
  return result;
}

}  // namespace softatlas::evidence
