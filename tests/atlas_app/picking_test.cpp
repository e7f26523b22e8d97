// Picking rays against the BVH, checked against a brute-force intersection of every triangle.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <limits>

#include "softatlas/app/picking.hpp"
#include "softatlas/io/organ_set.hpp"
#include "test_util.hpp"

namespace softatlas::app {
namespace {

struct Brute {
  int organ = -1;
  float t = std::numeric_limits<float>::max();
};

// Independent check: every triangle, plane intersection + barycentric inside test.
Brute brute_force(const std::vector<std::vector<float>>& P, const std::vector<std::vector<int32_t>>& F,
                  const Eigen::Vector3f& o, const Eigen::Vector3f& d) {
  Brute best;
  for (size_t m = 0; m < P.size(); ++m)
    for (size_t f = 0; f < F[m].size() / 3; ++f) {
      const Eigen::Vector3f a = Eigen::Map<const Eigen::Vector3f>(&P[m][3 * F[m][3 * f]]);
      const Eigen::Vector3f b = Eigen::Map<const Eigen::Vector3f>(&P[m][3 * F[m][3 * f + 1]]);
      const Eigen::Vector3f c = Eigen::Map<const Eigen::Vector3f>(&P[m][3 * F[m][3 * f + 2]]);
      const Eigen::Vector3f n = (b - a).cross(c - a);
      const float denom = n.dot(d);
      if (std::abs(denom) < 1e-12f) continue;
      const float t = n.dot(a - o) / denom;
      if (t <= 0 || t >= best.t) continue;
      const Eigen::Vector3f p = o + t * d;
      if ((b - a).cross(p - a).dot(n) < 0 || (c - b).cross(p - b).dot(n) < 0 || (a - c).cross(p - c).dot(n) < 0)
        continue;
      best = {static_cast<int>(m), t};
    }
  return best;
}

TEST(Picking, KnownRaysHitTheRightOrganAndAgreeWithBruteForce) {
  const io::OrganSet set = io::read_organ_set(test::atlas_dir());
  PickBvh bvh;
  std::vector<std::vector<float>> P;
  std::vector<std::vector<int32_t>> F;
  for (const auto& o : set.organs) {
    bvh.add_mesh(o.mesh.faces, o.mesh.vertex_count());
    P.emplace_back(o.mesh.vertices.begin(), o.mesh.vertices.end());
    F.push_back(o.mesh.faces);
  }
  std::vector<const float*> ptrs;
  for (auto& p : P) ptrs.push_back(p.data());
  bvh.build(ptrs);
  EXPECT_EQ(bvh.triangle_count(), 16180u);  // data/atlas, 10 structures
  // From the front (+y, RAS anterior) straight back through each organ's centroid.
  const Eigen::Vector3f back(0, -1, 0);
  // Known anatomy: from the front (+y) the liver is the first organ at its centroid; from behind
  // (-y) the kidneys are (they lie on the posterior wall).
  struct Case {
    const char* through;
    float side;
  };
  for (const Case c : {Case{"liver", 1.0f}, Case{"kidney_left", -1.0f}, Case{"kidney_right", -1.0f}}) {
    const auto& V = set.find(c.through)->mesh.vertices;
    Eigen::Vector3f centroid(0, 0, 0);
    for (size_t i = 0; i < V.size(); i += 3) centroid += Eigen::Vector3f(V[i], V[i + 1], V[i + 2]);
    centroid /= static_cast<float>(V.size() / 3);
    const Eigen::Vector3f origin = centroid + Eigen::Vector3f(0, 1000.0f * c.side, 0);
    const Eigen::Vector3f dir(0, -c.side, 0);
    const PickHit hit = bvh.intersect(origin, dir);
    ASSERT_GE(hit.organ, 0);
    EXPECT_EQ(set.organs[static_cast<size_t>(hit.organ)].name, c.through);
    const Brute b = brute_force(P, F, origin, dir);
    EXPECT_EQ(hit.organ, b.organ);
    EXPECT_NEAR(hit.t, b.t, 1e-2f);
    EXPECT_NEAR((hit.point - (origin + b.t * dir)).norm(), 0.0f, 1e-2f);
  }
  // 200 rays over the scene's bounding box: BVH == brute force every time.
  int hits = 0;
  for (int i = 0; i < 200; ++i) {
    const float x = -140.0f + 280.0f * static_cast<float>(i % 20) / 19.0f;
    const float z = 220.0f + 320.0f * static_cast<float>(i / 20) / 9.0f;  // the abdomen and heart
    const Eigen::Vector3f o(x, 1000.0f, z);
    const PickHit hit = bvh.intersect(o, back);
    const Brute b = brute_force(P, F, o, back);
    ASSERT_EQ(hit.organ, b.organ) << "ray " << i;
    if (hit.organ >= 0) {
      ++hits;
      EXPECT_NEAR(hit.t, b.t, 1e-2f);
    }
  }
  EXPECT_GT(hits, 40);
  EXPECT_LT(hits, 200);
  // A ray that misses everything.
  EXPECT_EQ(bvh.intersect(Eigen::Vector3f(0, 1000, 900), back).organ, -1);  // above the spinal cord
  // Hidden organs are skipped: the ray through the liver then reaches what lies behind it.
  std::vector<bool> visible(set.organs.size(), true);
  visible[static_cast<size_t>(set.index_of("liver"))] = false;
  const auto& L = set.find("liver")->mesh.vertices;
  const Eigen::Vector3f through_liver(static_cast<float>(L[0]), 1000.0f, static_cast<float>(L[2]));
  EXPECT_NE(bvh.intersect(through_liver, back, visible).organ, set.index_of("liver"));
}

TEST(Picking, RefitFollowsTheDeformedMesh) {
  const io::OrganSet set = io::read_organ_set(test::atlas_dir());
  const auto& liver = *set.find("liver");
  PickBvh bvh;
  bvh.add_mesh(liver.mesh.faces, liver.mesh.vertex_count());
  std::vector<float> P(liver.mesh.vertices.begin(), liver.mesh.vertices.end());
  bvh.build({P.data()});
  const Eigen::Vector3f o(59, 1000, 378), d(0, -1, 0);  // through the liver's centroid
  const PickHit before = bvh.intersect(o, d);
  ASSERT_EQ(before.organ, 0);
  // Move the liver 500 mm to the side: the old ray misses, a shifted ray hits at the same depth.
  for (size_t i = 0; i < P.size(); i += 3) P[i] += 500.0f;
  bvh.refit({P.data()});
  EXPECT_EQ(bvh.intersect(o, d).organ, -1);
  const PickHit after = bvh.intersect(o + Eigen::Vector3f(500, 0, 0), d);
  ASSERT_EQ(after.organ, 0);
  EXPECT_EQ(after.triangle, before.triangle);
  EXPECT_NEAR(after.t, before.t, 1e-3f);
}

}  // namespace
}  // namespace softatlas::app
