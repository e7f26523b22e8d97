// Geometry kernels on triangle surfaces: plain arrays in, plain arrays out (libigl style).
//
// Shapes: positions are SoA (x, y, z: #V each) or row-major V (#V*3); faces F are #F*3 vertex
// indices. No kernel allocates unless its output is a std::vector it returns.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace softatlas::sim {

// Unit vertex normals, paper 000 eq 1: the mean of the unit normals of the n_i incident faces
// (equal weights, Gouraud). N: #V*3. Isolated vertices get (0, 0, 0).
void vertex_normals(size_t nvert, const double* x, const double* y, const double* z, size_t nface, const int32_t* faces,
                    double* normals);

// Cotangent curvature normal, paper 000 eq 2 (Desbrun et al. 1999):
//   kappa_i N_i = 1 / (4 A_i) * sum_j (cot alpha_ij + cot beta_ij) (x_i - x_j)
// with A_i the area of the 1-ring. Accumulated per face: lap (#V*3, the cotangent Laplacian
// sum) and area2 (#V, twice the 1-ring area). Obtuse and degenerate triangles: a triangle with
// |e1 x e2| below `tiny` contributes nothing (its cotangents are unbounded); obtuse angles give
// negative cotangents, which eq 2 keeps (it is the mean-curvature normal, not a Voronoi mass).
// Adds into lap/area2 (the caller zeroes them).
void accumulate_cotan_laplacian(size_t nface, const int32_t* faces, const double* x, const double* y, const double* z,
                                double* lap_x, double* lap_y, double* lap_z, double* area2);

// Mean curvature |kappa_i| = |L_i| / (4 A_i) = |L_i| / (2 area2_i) per vertex, from the
// accumulators of accumulate_cotan_laplacian. Eq 2 gives 2H N for the sum / (2 A), so kappa_i
// here is the mean curvature H (1/r on a sphere of radius r). kappa: #V.
void mean_curvature_from_laplacian(size_t nvert, const double* lap_x, const double* lap_y, const double* lap_z,
                                   const double* area2, double* kappa);

// Convenience: per-vertex mean curvature of a mesh given row-major V (#V*3).
std::vector<double> mean_curvature(const std::vector<double>& V, const std::vector<int32_t>& F);

// Signed volume enclosed by a closed, outward-oriented surface (divergence theorem):
//   V = 1/6 sum_f x_i . (x_j x x_k). Faces [face_begin, face_end).
double enclosed_volume(const double* x, const double* y, const double* z, const int32_t* faces, size_t face_begin,
                       size_t face_end);
double enclosed_volume(const std::vector<double>& V, const std::vector<int32_t>& F);
// Its gradient (003 eqs 27-30 on the fan of tetrahedra the faces make with the origin):
// grad_i V = 1/6 sum_{faces (i,j,k)} x_j x x_k, added into gx, gy, gz.
// Vertex indices are faces[...] - offset in x, y, z and the gradient arrays.
void add_volume_gradient(const double* x, const double* y, const double* z, const int32_t* faces, size_t face_begin,
                         size_t face_end, int32_t offset, double* gx, double* gy, double* gz);

// Surface area of faces [begin, end).
double surface_area(const double* x, const double* y, const double* z, const int32_t* faces, size_t face_begin,
                    size_t face_end);

// Per-vertex masses, paper 000 eq 8: mu_i = mu * sum_{faces at i} A_j / (3 A), A the total
// area. Adds into mass (#V) for faces [begin, end) with total mass `total_mass`.
void area_masses(const double* x, const double* y, const double* z, const int32_t* faces, size_t face_begin,
                 size_t face_end, double total_mass, double* mass);

// Spring stiffness, paper 000 eq 9 (Lloyd et al. 2007):
//   k_ij = E t sum_{faces at edge ij} (sqrt(3) / 4) A_j / A_0,  A_0 = sqrt(3)/4 |e_ij|^2
// i.e. E t sum A_j / |e_ij|^2. `face_area_sum` is the summed area of the 1 or 2 faces at the edge.
inline double lloyd_stiffness(double young_modulus, double thickness, double face_area_sum, double rest_length) {
  const double a0 = 0.4330127018922193 * rest_length * rest_length;
  return young_modulus * thickness * 0.4330127018922193 * face_area_sum / a0;
}

// Spring damping, paper 000 eq 10 (Paloc et al. 2002) printed as d_ij = 2 sqrt(k_ij (mu_i + mu_j)) / l0.
// As printed it has units kg/(m s), not N s/m: eq 7 multiplies d by a velocity, so d must be
// N s/m. We use eq 10 without the 1/l0, d_ij = 2 sqrt(k_ij (mu_i + mu_j)), which is (up to the
// factor sqrt(2) of reduced vs summed mass) the critical damping of the spring. docs/physics.md.
inline double spring_damping(double stiffness, double mass_i, double mass_j);

// Dihedral angle at an interior edge (a, b) between faces (a, b, c) and (b, a, d), signed so
// that a convex fold of an outward-oriented surface is positive. Used by flexion springs.
double dihedral_angle(const double* pa, const double* pb, const double* pc, const double* pd);

}  // namespace softatlas::sim

#include <cmath>
inline double softatlas::sim::spring_damping(double stiffness, double mass_i, double mass_j) {
  return 2.0 * std::sqrt(stiffness * (mass_i + mass_j));
}
