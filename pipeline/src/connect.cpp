// Stage 5, connect: for each pair of organs (default anatomical pairs, plus any pair whose
// surfaces come closer than the threshold) connect surface vertices of A to their closest
// vertices of B within the threshold, thinned to one spring per disc of spacing_mm on A.
// Closest points come from a k-d tree (vtkKdTreePointLocator) over B's vertices.
#include <vtkIdList.h>
#include <vtkKdTreePointLocator.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>

#include <algorithm>
#include <cmath>
#include <unordered_map>
#include <unordered_set>

#include "softatlas/pipeline/connect.hpp"

namespace softatlas::pipeline {
namespace {

struct Candidate {
  double d;
  int32_t a, b;
};

double dist(const double* p, const double* q) {
  return std::sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2]));
}

bool is_default_pair(const ConnectOptions& o, const std::string& a, const std::string& b) {
  for (const auto& p : o.pairs)
    if ((p.first == a && p.second == b) || (p.first == b && p.second == a)) return true;
  return false;
}

}  // namespace

std::vector<io::Connection> connect_organs(const std::vector<io::OrganEntry>& organs, const ConnectOptions& o,
                                           std::vector<PairReport>* report) {
  std::vector<io::Connection> springs;
  std::vector<vtkSmartPointer<vtkKdTreePointLocator>> trees(organs.size());
  std::vector<vtkSmartPointer<vtkPolyData>> clouds(organs.size());
  for (size_t i = 0; i < organs.size(); ++i) {
    vtkNew<vtkPoints> pts;
    pts->SetDataTypeToDouble();
    const auto& V = organs[i].mesh.vertices;
    for (size_t v = 0; v < V.size() / 3; ++v) pts->InsertNextPoint(&V[3 * v]);
    clouds[i] = vtkSmartPointer<vtkPolyData>::New();
    clouds[i]->SetPoints(pts);
    trees[i] = vtkSmartPointer<vtkKdTreePointLocator>::New();
    trees[i]->SetDataSet(clouds[i]);
    trees[i]->BuildLocator();
  }
  for (size_t ia = 0; ia < organs.size(); ++ia)
    for (size_t ib = ia + 1; ib < organs.size(); ++ib) {
      const auto& A = organs[ia];
      const auto& B = organs[ib];
      // Springs hang from the organ with fewer vertices so that thinning works on the coarser one.
      const bool swap = A.mesh.vertex_count() > B.mesh.vertex_count();
      const auto& from = swap ? B : A;
      const auto& to = swap ? A : B;
      auto& tree = trees[swap ? ia : ib];
      std::vector<Candidate> cand;
      double closest = 1e300;
      for (size_t v = 0; v < from.mesh.vertex_count(); ++v) {
        const double* p = &from.mesh.vertices[3 * v];
        const vtkIdType w = tree->FindClosestPoint(p);
        const double d = dist(p, &to.mesh.vertices[3 * w]);
        closest = std::min(closest, d);
        if (d <= o.distance_mm) cand.push_back({d, static_cast<int32_t>(v), static_cast<int32_t>(w)});
      }
      const bool dflt = is_default_pair(o, A.name, B.name);
      if (!dflt && closest > o.distance_mm) continue;
      std::sort(cand.begin(), cand.end(),
                [](const Candidate& x, const Candidate& y) { return x.d < y.d || (x.d == y.d && x.a < y.a); });
      // Greedy Poisson-disc thinning on the source organ, closest pairs first; each target
      // vertex takes at most one spring.
      std::vector<int32_t> accepted;
      std::unordered_set<int32_t> used_b;
      size_t count = 0;
      for (const Candidate& c : cand) {
        if (used_b.count(c.b)) continue;
        const double* p = &from.mesh.vertices[3 * c.a];
        bool near = false;
        for (int32_t q : accepted)
          if (dist(p, &from.mesh.vertices[3 * q]) < o.spacing_mm) {
            near = true;
            break;
          }
        if (near) continue;
        accepted.push_back(c.a);
        used_b.insert(c.b);
        io::Connection s;
        s.organ_a = from.name;
        s.vertex_a = c.a;
        s.organ_b = to.name;
        s.vertex_b = c.b;
        s.rest_length_mm = c.d;
        s.stiffness = o.stiffness;
        springs.push_back(s);
        ++count;
      }
      if (report) report->push_back({from.name, to.name, closest, count, dflt});
    }
  return springs;
}

}  // namespace softatlas::pipeline
