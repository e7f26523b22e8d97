// Geometry kernels (paper 000 eqs 1, 2, 8; enclosed volume by the divergence theorem).
#include "softatlas/sim/geometry.hpp"

#include <algorithm>
#include <cmath>

namespace softatlas::sim {
namespace {
constexpr double kTinyArea2 = 1e-300;
}

void vertex_normals(size_t nvert, const double* x, const double* y, const double* z, size_t nface, const int32_t* faces,
                    double* normals) {
  std::vector<int32_t> count(nvert, 0);
  std::fill(normals, normals + 3 * nvert, 0.0);
  for (size_t f = 0; f < nface; ++f) {
    const int32_t i = faces[3 * f], j = faces[3 * f + 1], k = faces[3 * f + 2];
    const double ux = x[j] - x[i], uy = y[j] - y[i], uz = z[j] - z[i];
    const double vx = x[k] - x[i], vy = y[k] - y[i], vz = z[k] - z[i];
    double cx = uy * vz - uz * vy, cy = uz * vx - ux * vz, cz = ux * vy - uy * vx;
    const double len = std::sqrt(cx * cx + cy * cy + cz * cz);
    if (!(len > kTinyArea2)) continue;  // degenerate face: no direction to contribute
    cx /= len, cy /= len, cz /= len;
    for (int32_t v : {i, j, k}) {
      normals[3 * v] += cx, normals[3 * v + 1] += cy, normals[3 * v + 2] += cz;
      ++count[v];
    }
  }
  // Eq 1 divides by n_i; we normalise to unit length, which has the same direction.
  for (size_t v = 0; v < nvert; ++v) {
    double* n = normals + 3 * v;
    const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (len > 0) n[0] /= len, n[1] /= len, n[2] /= len;
  }
}

void accumulate_cotan_laplacian(size_t nface, const int32_t* faces, const double* x, const double* y, const double* z,
                                double* lap_x, double* lap_y, double* lap_z, double* area2) {
  for (size_t f = 0; f < nface; ++f) {
    const int32_t i = faces[3 * f], j = faces[3 * f + 1], k = faces[3 * f + 2];
    const double eijx = x[j] - x[i], eijy = y[j] - y[i], eijz = z[j] - z[i];
    const double ejkx = x[k] - x[j], ejky = y[k] - y[j], ejkz = z[k] - z[j];
    const double ekix = x[i] - x[k], ekiy = y[i] - y[k], ekiz = z[i] - z[k];
    const double cx = eijy * ekiz - eijz * ekiy;
    const double cy = eijz * ekix - eijx * ekiz;
    const double cz = eijx * ekiy - eijy * ekix;
    const double a2 = std::sqrt(cx * cx + cy * cy + cz * cz);  // |cross| = 2 area
    // A sliver's cotangents are unbounded: it adds no curvature and no area (a branch-free
    // select keeps the loop vectorisable).
    const double inv = a2 > kTinyArea2 ? 1.0 / a2 : 0.0;
    const double cot_i = -(eijx * ekix + eijy * ekiy + eijz * ekiz) * inv;
    const double cot_j = -(ejkx * eijx + ejky * eijy + ejkz * eijz) * inv;
    const double cot_k = -(ekix * ejkx + ekiy * ejky + ekiz * ejkz) * inv;
    const double lix = cot_j * ekix - cot_k * eijx, liy = cot_j * ekiy - cot_k * eijy,
                 liz = cot_j * ekiz - cot_k * eijz;
    const double ljx = cot_k * eijx - cot_i * ejkx, ljy = cot_k * eijy - cot_i * ejky,
                 ljz = cot_k * eijz - cot_i * ejkz;
    lap_x[i] += lix, lap_y[i] += liy, lap_z[i] += liz, area2[i] += a2;
    lap_x[j] += ljx, lap_y[j] += ljy, lap_z[j] += ljz, area2[j] += a2;
    lap_x[k] -= lix + ljx, lap_y[k] -= liy + ljy, lap_z[k] -= liz + ljz, area2[k] += a2;
  }
}

void mean_curvature_from_laplacian(size_t nvert, const double* lap_x, const double* lap_y, const double* lap_z,
                                   const double* area2, double* kappa) {
  // The cotangent sum equals 4 A_i H N with A_i the vertex's (barycentric) area share
  // (Meyer et al. 2003). Eq 2 as printed divides by 4 A with A the *whole* 1-ring area, which is
  // 3 A_i, and so yields H / 3. We return the mean curvature H itself (1/r on a sphere):
  // H = |sum| / (4 A_1ring / 3) = 1.5 |sum| / area2. docs/physics.md, "curvature scale".
  for (size_t v = 0; v < nvert; ++v) {
    const double l = std::sqrt(lap_x[v] * lap_x[v] + lap_y[v] * lap_y[v] + lap_z[v] * lap_z[v]);
    kappa[v] = area2[v] > kTinyArea2 ? 1.5 * l / area2[v] : 0.0;
  }
}

std::vector<double> mean_curvature(const std::vector<double>& V, const std::vector<int32_t>& F) {
  const size_t n = V.size() / 3;
  std::vector<double> x(n), y(n), z(n), lx(n), ly(n), lz(n), a2(n), kappa(n);
  for (size_t i = 0; i < n; ++i) x[i] = V[3 * i], y[i] = V[3 * i + 1], z[i] = V[3 * i + 2];
  accumulate_cotan_laplacian(F.size() / 3, F.data(), x.data(), y.data(), z.data(), lx.data(), ly.data(), lz.data(),
                             a2.data());
  mean_curvature_from_laplacian(n, lx.data(), ly.data(), lz.data(), a2.data(), kappa.data());
  return kappa;
}

double enclosed_volume(const double* x, const double* y, const double* z, const int32_t* faces, size_t face_begin,
                       size_t face_end) {
  double v6 = 0.0;
  for (size_t f = face_begin; f < face_end; ++f) {
    const int32_t i = faces[3 * f], j = faces[3 * f + 1], k = faces[3 * f + 2];
    // x_i . (x_j x x_k)
    v6 += x[i] * (y[j] * z[k] - z[j] * y[k]) + y[i] * (z[j] * x[k] - x[j] * z[k]) + z[i] * (x[j] * y[k] - y[j] * x[k]);
  }
  return v6 / 6.0;
}

void add_volume_gradient(const double* x, const double* y, const double* z, const int32_t* faces, size_t face_begin,
                         size_t face_end, int32_t offset, double* gx, double* gy, double* gz) {
  auto add = [&](int32_t v, int32_t p, int32_t q) {  // x_p x x_q / 6
    gx[v] += (y[p] * z[q] - z[p] * y[q]) / 6.0;
    gy[v] += (z[p] * x[q] - x[p] * z[q]) / 6.0;
    gz[v] += (x[p] * y[q] - y[p] * x[q]) / 6.0;
  };
  for (size_t f = face_begin; f < face_end; ++f) {
    const int32_t i = faces[3 * f] - offset, j = faces[3 * f + 1] - offset, k = faces[3 * f + 2] - offset;
    add(i, j, k), add(j, k, i), add(k, i, j);
  }
}

double enclosed_volume(const std::vector<double>& V, const std::vector<int32_t>& F) {
  // Relative to the first vertex to keep the sum well conditioned far from the origin.
  const size_t n = V.size() / 3;
  if (n == 0) return 0.0;
  std::vector<double> x(n), y(n), z(n);
  for (size_t i = 0; i < n; ++i) x[i] = V[3 * i] - V[0], y[i] = V[3 * i + 1] - V[1], z[i] = V[3 * i + 2] - V[2];
  return enclosed_volume(x.data(), y.data(), z.data(), F.data(), 0, F.size() / 3);
}

double surface_area(const double* x, const double* y, const double* z, const int32_t* faces, size_t face_begin,
                    size_t face_end) {
  double a = 0.0;
  for (size_t f = face_begin; f < face_end; ++f) {
    const int32_t i = faces[3 * f], j = faces[3 * f + 1], k = faces[3 * f + 2];
    const double ux = x[j] - x[i], uy = y[j] - y[i], uz = z[j] - z[i];
    const double vx = x[k] - x[i], vy = y[k] - y[i], vz = z[k] - z[i];
    const double cx = uy * vz - uz * vy, cy = uz * vx - ux * vz, cz = ux * vy - uy * vx;
    a += 0.5 * std::sqrt(cx * cx + cy * cy + cz * cz);
  }
  return a;
}

void area_masses(const double* x, const double* y, const double* z, const int32_t* faces, size_t face_begin,
                 size_t face_end, double total_mass, double* mass) {
  const double area = surface_area(x, y, z, faces, face_begin, face_end);
  if (!(area > 0.0)) return;
  for (size_t f = face_begin; f < face_end; ++f) {
    const int32_t i = faces[3 * f], j = faces[3 * f + 1], k = faces[3 * f + 2];
    const double a = surface_area(x, y, z, faces, f, f + 1);
    const double share = total_mass * a / (3.0 * area);  // eq 8
    mass[i] += share, mass[j] += share, mass[k] += share;
  }
}

double dihedral_angle(const double* pa, const double* pb, const double* pc, const double* pd) {
  // Faces (a, b, c) and (b, a, d) share edge ab. n1 = (b - a) x (c - a), n2 = (a - b) x (d - b).
  const double e[3] = {pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]};
  const double u[3] = {pc[0] - pa[0], pc[1] - pa[1], pc[2] - pa[2]};
  const double w[3] = {pd[0] - pa[0], pd[1] - pa[1], pd[2] - pa[2]};
  const double n1[3] = {e[1] * u[2] - e[2] * u[1], e[2] * u[0] - e[0] * u[2], e[0] * u[1] - e[1] * u[0]};
  // (a - b) x (d - b) = (-e) x (w - e) = -e x w
  const double n2[3] = {-(e[1] * w[2] - e[2] * w[1]), -(e[2] * w[0] - e[0] * w[2]), -(e[0] * w[1] - e[1] * w[0])};
  const double el = std::sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
  const double cosv = n1[0] * n2[0] + n1[1] * n2[1] + n1[2] * n2[2];
  const double c12[3] = {n1[1] * n2[2] - n1[2] * n2[1], n1[2] * n2[0] - n1[0] * n2[2], n1[0] * n2[1] - n1[1] * n2[0]};
  const double sinv = el > 0 ? (c12[0] * e[0] + c12[1] * e[1] + c12[2] * e[2]) / el : 0.0;
  // Angle between the normals, signed by the fold direction about e.
  return std::atan2(sinv, cosv);
}

}  // namespace softatlas::sim
