// Stage 3, surface (VTK), read as a pipeline:
//   label mask (cropped, padded) -> vtkDiscreteFlyingEdges3D (index space) -> voxel-to-RAS
//   transform -> vtkWindowedSincPolyDataFilter (world mm, so anisotropic voxels smooth evenly)
//   -> specks removed -> outward orientation.
#include <vtkCellArray.h>
#include <vtkDiscreteFlyingEdges3D.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkUnsignedCharArray.h>
#include <vtkWindowedSincPolyDataFilter.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "softatlas/pipeline/surface.hpp"
#include "softatlas/pipeline/topology.hpp"
#include "softatlas/sim/error.hpp"

namespace softatlas::pipeline {
namespace {

double component_signed_volume(const io::TriMesh& m, const std::vector<int>& comp, int id) {
  double v = 0;
  for (size_t f = 0; f < m.face_count(); ++f) {
    if (comp[f] != id) continue;
    const double* p0 = &m.vertices[3 * m.faces[3 * f]];
    const double* p1 = &m.vertices[3 * m.faces[3 * f + 1]];
    const double* p2 = &m.vertices[3 * m.faces[3 * f + 2]];
    v += (p0[0] * (p1[1] * p2[2] - p1[2] * p2[1]) - p0[1] * (p1[0] * p2[2] - p1[2] * p2[0]) +
          p0[2] * (p1[0] * p2[1] - p1[1] * p2[0])) /
         6.0;
  }
  return v;
}

}  // namespace

SurfaceResult label_surface(const Volume& labels, const std::vector<int>& values, const SurfaceOptions& options,
                            const std::string& where) {
  SurfaceResult out;
  const std::set<int> wanted(values.begin(), values.end());
  const int nx = labels.dims[0], ny = labels.dims[1], nz = labels.dims[2];
  // Bounding box of the organ's voxels: only that block (plus a zero border, so that organs cut
  // by the volume edge still get closed caps) goes through flying edges.
  int lo[3] = {nx, ny, nz}, hi[3] = {-1, -1, -1};
  const int vmin = *wanted.begin(), vmax = *wanted.rbegin();
  auto in = [&](size_t idx) {
    const float x = labels.values[idx];
    if (x < vmin - 0.5f || x > vmax + 0.5f) return false;
    return wanted.count(static_cast<int>(std::lround(x))) > 0;
  };
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        const size_t idx = labels.index(i, j, k);
        if (!in(idx)) continue;
        ++out.mask_voxels;
        lo[0] = std::min(lo[0], i), lo[1] = std::min(lo[1], j), lo[2] = std::min(lo[2], k);
        hi[0] = std::max(hi[0], i), hi[1] = std::max(hi[1], j), hi[2] = std::max(hi[2], k);
      }
  if (out.mask_voxels == 0) throw InputError(where, "the label is empty (no voxels)");
  out.mask_volume_mm3 = static_cast<double>(out.mask_voxels) * labels.voxel_volume_mm3();

  const int ex = hi[0] - lo[0] + 3, ey = hi[1] - lo[1] + 3, ez = hi[2] - lo[2] + 3;
  vtkNew<vtkImageData> mask;
  mask->SetDimensions(ex, ey, ez);
  mask->SetOrigin(lo[0] - 1, lo[1] - 1, lo[2] - 1);  // index space: points come out as (i, j, k)
  mask->SetSpacing(1, 1, 1);
  mask->AllocateScalars(VTK_UNSIGNED_CHAR, 1);
  auto* m = static_cast<unsigned char*>(mask->GetScalarPointer());
  std::fill(m, m + static_cast<size_t>(ex) * ey * ez, 0);
  for (int k = lo[2]; k <= hi[2]; ++k)
    for (int j = lo[1]; j <= hi[1]; ++j)
      for (int i = lo[0]; i <= hi[0]; ++i)
        if (in(labels.index(i, j, k)))
          m[(i - lo[0] + 1) + static_cast<size_t>(ex) * ((j - lo[1] + 1) + static_cast<size_t>(ey) * (k - lo[2] + 1))] =
              1;

  vtkNew<vtkDiscreteFlyingEdges3D> flying_edges;
  flying_edges->SetInputData(mask);
  flying_edges->SetValue(0, 1);
  flying_edges->ComputeNormalsOff();
  flying_edges->ComputeGradientsOff();
  flying_edges->ComputeScalarsOff();
  flying_edges->Update();
  vtkPolyData* iso = flying_edges->GetOutput();

  // Voxel indices -> RAS mm with the full affine (direction, spacing, origin).
  vtkNew<vtkPolyData> world;
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToDouble();
  pts->SetNumberOfPoints(iso->GetNumberOfPoints());
  for (vtkIdType p = 0; p < iso->GetNumberOfPoints(); ++p) {
    double x[3];
    iso->GetPoint(p, x);
    const auto w = labels.world(x[0], x[1], x[2]);
    pts->SetPoint(p, w[0], w[1], w[2]);
  }
  world->SetPoints(pts);
  world->SetPolys(iso->GetPolys());

  vtkNew<vtkWindowedSincPolyDataFilter> smoother;
  smoother->SetInputData(world);
  smoother->SetNumberOfIterations(options.smoothing_iterations);
  smoother->SetPassBand(options.smoothing_passband);
  smoother->BoundarySmoothingOff();
  smoother->FeatureEdgeSmoothingOff();
  smoother->NonManifoldSmoothingOn();
  smoother->NormalizeCoordinatesOn();  // windowed sinc is only stable on normalised coordinates
  smoother->Update();
  vtkPolyData* smooth = options.smoothing_iterations > 0 ? smoother->GetOutput() : world.Get();

  io::TriMesh mesh;
  mesh.vertices.resize(3 * static_cast<size_t>(smooth->GetNumberOfPoints()));
  for (vtkIdType p = 0; p < smooth->GetNumberOfPoints(); ++p) smooth->GetPoint(p, &mesh.vertices[3 * p]);
  vtkCellArray* polys = smooth->GetPolys();
  vtkIdType npts;
  const vtkIdType* ids;
  for (polys->InitTraversal(); polys->GetNextCell(npts, ids);)
    if (npts == 3)
      for (int c = 0; c < 3; ++c) mesh.faces.push_back(static_cast<int32_t>(ids[c]));

  // Specks: components whose enclosed volume is under a small share of the organ's volume.
  // Flying edges orients each piece consistently; the sign of its volume tells inward/outward.
  int ncomp = 0;
  const auto comp = face_components(mesh, &ncomp);
  std::vector<double> vol(ncomp);
  double total = 0;
  for (int c = 0; c < ncomp; ++c) {
    vol[c] = component_signed_volume(mesh, comp, c);
    total += std::abs(vol[c]);
  }
  std::vector<char> keep(mesh.face_count(), 0);
  for (int c = 0; c < ncomp; ++c) {
    const double share = std::abs(vol[c]) / std::max(total, 1e-12);
    if (share < options.speck_share) {
      ++out.specks_removed;
      out.specks_volume_mm3 += std::abs(vol[c]);
      continue;
    }
    ++out.pieces_kept;
    if (share > options.large_piece_share) ++out.large_pieces;
  }
  for (size_t f = 0; f < mesh.face_count(); ++f)
    keep[f] = std::abs(vol[comp[f]]) / std::max(total, 1e-12) >= options.speck_share;
  // Outward: flip every kept piece whose signed volume is negative. Cavities (a piece inside
  // another) do not occur for a label's outer boundary at this stage, because the discrete
  // surface of a hollow label would be two nested pieces; those are flipped the same way and
  // CGAL's orient_to_bound_a_volume decides nesting in stage 4.
  for (size_t f = 0; f < mesh.face_count(); ++f)
    if (keep[f] && vol[comp[f]] < 0) std::swap(mesh.faces[3 * f + 1], mesh.faces[3 * f + 2]);
  out.mesh = select_faces(mesh, keep);
  return out;
}

}  // namespace softatlas::pipeline
