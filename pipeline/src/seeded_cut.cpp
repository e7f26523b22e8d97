// Seeded graph-cut segmentation; the energy is described in seeded_cut.hpp, the measurements in
// docs/pipeline.md ("Seeded segmentation").
#include "seeded_cut.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>

#include "softatlas/pipeline/label_table.hpp"
#include "graph_cut.hpp"
#include "grid.hpp"

namespace softatlas::pipeline {
namespace {

// Anatomical priors per organ: radius (mm, the distance from its seed tree to its boundary that
// costs nothing), an upper volume bound (mL, adult organs, generous), and the organ's HU in
// unenhanced and in contrast-enhanced CT (typical values; NaN: content varies, no prior).
struct OrganPrior {
  double radius_mm, max_ml, unenhanced_hu, enhanced_hu, hu_sd;
};
OrganPrior prior_of(const std::string& name) {
  const double none = std::numeric_limits<double>::quiet_NaN();
  static const std::map<std::string, OrganPrior> table = {
      {"liver", {40, 3500, 55, 100, 30}},
      {"spleen", {25, 1000, 45, 110, 30}},
      {"stomach", {30, 2500, none, none, 0}},
      {"pancreas", {12, 250, 40, 100, 30}},
      {"gallbladder", {15, 200, 10, 10, 20}},
      {"kidney_left", {25, 450, 30, 150, 40}},
      {"kidney_right", {25, 450, 30, 150, 40}},
      {"adrenal_gland_left", {5, 30, 30, 60, 30}},
      {"adrenal_gland_right", {5, 30, 30, 60, 30}},
      {"aorta", {15, 500, 40, 250, 100}},
      {"inferior_vena_cava", {12, 300, 40, 120, 50}},
      {"portal_vein_and_splenic_vein", {8, 150, 40, 150, 50}},
      {"heart", {45, 1500, 40, 300, 150}},
      {"urinary_bladder", {30, 800, 10, 10, 20}},
      {"colon", {20, 2500, none, none, 0}},
      {"small_bowel", {20, 2500, none, none, 0}},
      {"duodenum", {12, 300, none, none, 0}},
      {"esophagus", {8, 100, 40, 60, 30}},
  };
  const auto it = table.find(name);
  if (it != table.end()) return it->second;
  if (name.rfind("lung", 0) == 0) return {50, 4000, -850, -850, 60};
  return {20, 2000, none, none, 0};
}

// Histograms over [kLo, kHi) in kBin-HU bins.
constexpr double kLo = -1100, kHi = 3300, kBin = 2;
constexpr int kBins = static_cast<int>((kHi - kLo) / kBin);
int bin_of(double v) { return std::clamp(static_cast<int>((v - kLo) / kBin), 0, kBins - 1); }

// Gaussian kernel density from a histogram of counts: normalised, bandwidth h HU.
std::vector<double> density(const std::vector<double>& counts, double h) {
  const int r = static_cast<int>(std::ceil(3 * h / kBin));
  std::vector<double> w(2 * r + 1);
  for (int t = -r; t <= r; ++t) w[t + r] = std::exp(-0.5 * (t * kBin) * (t * kBin) / (h * h));
  std::vector<double> out(kBins, 0.0);
  double total = 0;
  for (int b = 0; b < kBins; ++b) {
    if (counts[b] == 0) continue;
    for (int t = -r; t <= r; ++t)
      if (b + t >= 0 && b + t < kBins) out[b + t] += counts[b] * w[t + r];
  }
  for (double x : out) total += x;
  for (double& x : out) x = total > 0 ? x / total : 1.0 / kBins;
  return out;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

struct Segment3 {
  std::array<double, 3> a, b;
};

double distance_to(const std::vector<Segment3>& tree, const std::array<double, 3>& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& s : tree) {
    double ab[3], ap[3], l2 = 0, t = 0;
    for (int c = 0; c < 3; ++c) ab[c] = s.b[c] - s.a[c], ap[c] = p[c] - s.a[c], l2 += ab[c] * ab[c], t += ab[c] * ap[c];
    t = l2 > 0 ? std::clamp(t / l2, 0.0, 1.0) : 0.0;
    double d2 = 0;
    for (int c = 0; c < 3; ++c) d2 += (ap[c] - t * ab[c]) * (ap[c] - t * ab[c]);
    best = std::min(best, d2);
  }
  return std::sqrt(best);
}

// Minimum spanning tree (Prim) of the seed points, as segments; one seed gives a point.
std::vector<Segment3> seed_tree(const std::vector<std::array<double, 3>>& pts) {
  std::vector<Segment3> tree;
  if (pts.size() == 1) return {{pts[0], pts[0]}};
  std::vector<char> in(pts.size(), 0);
  std::vector<double> best(pts.size(), std::numeric_limits<double>::infinity());
  std::vector<size_t> from(pts.size(), 0);
  size_t cur = 0;
  in[0] = 1;
  for (size_t added = 1; added < pts.size(); ++added) {
    for (size_t j = 0; j < pts.size(); ++j) {
      if (in[j]) continue;
      double d2 = 0;
      for (int c = 0; c < 3; ++c) d2 += (pts[j][c] - pts[cur][c]) * (pts[j][c] - pts[cur][c]);
      if (d2 < best[j]) best[j] = d2, from[j] = cur;
    }
    size_t next = 0;
    double bd = std::numeric_limits<double>::infinity();
    for (size_t j = 0; j < pts.size(); ++j)
      if (!in[j] && best[j] < bd) bd = best[j], next = j;
    in[next] = 1;
    tree.push_back({pts[from[next]], pts[next]});
    cur = next;
  }
  return tree;
}

}  // namespace

std::vector<int16_t> seeded_cut(const Volume& ct, const std::vector<float>& smooth, const std::vector<CutOrgan>& organs,
                                const std::vector<size_t>& background, const SegmentOptions& o) {
  const auto& d = ct.dims;
  const size_t n = smooth.size();
  const auto sp = spacing_mm(ct);
  const double voxel_mm3 = sp[0] * sp[1] * sp[2];
  auto ijk = [&](size_t v) {
    return std::array<int, 3>{static_cast<int>(v % d[0]), static_cast<int>((v / d[0]) % d[1]),
                              static_cast<int>(v / (static_cast<size_t>(d[0]) * d[1]))};
  };
  auto world = [&](size_t v) {
    const auto c = ijk(v);
    return ct.world(c[0], c[1], c[2]);
  };

  // Noise of the smoothed image: robust sd of differences between x-neighbours in soft tissue.
  std::vector<double> diffs;
  for (size_t v = 0; v + 1 < n; v += 7)
    if (smooth[v] > -200 && smooth[v] < 300 && smooth[v + 1] > -200 && smooth[v + 1] < 300 && (v + 1) % d[0] != 0)
      diffs.push_back(std::abs(smooth[v + 1] - smooth[v]));
  const double noise = diffs.empty() ? 10.0 : 1.4826 * median(diffs) / std::sqrt(2.0);
  const double h = std::max(o.cut_bandwidth_min_hu, 1.5 * noise);
  const double edge_sigma = std::max(o.cut_edge_sigma_min_hu, 2.0 * noise);

  // Background model: the whole image's histogram.
  std::vector<double> all(kBins, 0.0);
  for (float v : smooth) all[bin_of(v)] += 1;
  const std::vector<double> p_image = density(all, h);

  // Seed samples (smoothed values within seed_radius_mm of each seed), and the contrast phase:
  // enhanced when the aorta's seeds (else the liver's, spleen's or kidneys') read bright.
  std::vector<std::vector<double>> samples(organs.size());
  const int reach[3] = {static_cast<int>(o.seed_radius_mm / sp[0]), static_cast<int>(o.seed_radius_mm / sp[1]),
                        static_cast<int>(o.seed_radius_mm / sp[2])};
  for (size_t r = 0; r < organs.size(); ++r)
    for (size_t s : organs[r].seeds) {
      const auto c = ijk(s);
      for (int z = -reach[2]; z <= reach[2]; ++z)
        for (int y = -reach[1]; y <= reach[1]; ++y)
          for (int x = -reach[0]; x <= reach[0]; ++x) {
            const double r2 = (x * sp[0]) * (x * sp[0]) + (y * sp[1]) * (y * sp[1]) + (z * sp[2]) * (z * sp[2]);
            const int a = c[0] + x, b = c[1] + y, e = c[2] + z;
            if (r2 > o.seed_radius_mm * o.seed_radius_mm || a < 0 || b < 0 || e < 0 || a >= d[0] || b >= d[1] ||
                e >= d[2])
              continue;
            samples[r].push_back(smooth[ct.index(a, b, e)]);
          }
    }
  double phase_hu = std::numeric_limits<double>::quiet_NaN(), phase_threshold = 0;
  std::string phase_from;
  for (const auto& [name, threshold] : std::vector<std::pair<std::string, double>>{
           {"aorta", 130}, {"liver", 80}, {"spleen", 80}, {"kidney_left", 80}, {"kidney_right", 80}})
    for (size_t r = 0; r < organs.size() && phase_from.empty(); ++r)
      if (label_name(organs[r].id) == name)
        phase_hu = median(samples[r]), phase_threshold = threshold, phase_from = name;
  const bool enhanced = !phase_from.empty() && phase_hu > phase_threshold;
  std::fprintf(stderr, "[softatlas segment] graph cut; contrast phase: %s (%s seeds median %.0f HU); noise %.0f HU\n",
               phase_from.empty() ? "unknown, no prior"
               : enhanced         ? "enhanced"
                                  : "unenhanced",
               phase_from.empty() ? "no aorta/liver/spleen/kidney" : phase_from.c_str(), phase_hu, noise);

  // Per organ: data term (nats per voxel) cached over the whole grid is too large for many
  // organs; it is computed per box.
  std::vector<std::vector<float>> gain(organs.size());  // log p_organ - log p_image per bin
  std::vector<OrganPrior> priors;
  for (size_t r = 0; r < organs.size(); ++r) {
    OrganPrior pr = prior_of(label_name(organs[r].id));
    pr.radius_mm *= o.cut_radius_scale;
    priors.push_back(pr);
    std::vector<double> counts(kBins, 0.0);
    for (double v : samples[r]) counts[bin_of(v)] += 1;
    std::vector<double> p = density(counts, h);
    // Five seeds may miss part of an organ's range (the chambers' densest contrast when most
    // seeds lie in the myocardium): a flat window of the seeds' mean - 2.5 sd .. mean + 4 sd
    // (sd clamped to 20-100 HU, as the region growing's window) carries a share of the density.
    double s1 = 0, s2 = 0;
    for (double v : samples[r]) s1 += v, s2 += v * v;
    const double cnt = std::max<double>(1, samples[r].size()), mu = s1 / cnt;
    const double sd = std::clamp(std::sqrt(std::max(0.0, s2 / cnt - mu * mu)), 20.0, o.intensity_sigma_max_hu);
    std::vector<double> window(kBins, 0.0);
    for (int b = bin_of(mu - o.intensity_sigma_scale * sd); b <= bin_of(mu + o.intensity_sigma_scale_high * sd); ++b)
      window[b] = 1;
    const std::vector<double> pw = density(window, h);
    for (int b = 0; b < kBins; ++b) p[b] = (1 - o.cut_window_weight) * p[b] + o.cut_window_weight * pw[b];
    const double prior_hu = enhanced ? pr.enhanced_hu : pr.unenhanced_hu;
    if (!phase_from.empty() && std::isfinite(prior_hu)) {
      std::vector<double> pc(kBins, 0.0);
      pc[bin_of(prior_hu)] = 1;
      const std::vector<double> pp = density(pc, std::max(h, pr.hu_sd));
      for (int b = 0; b < kBins; ++b) p[b] = (1 - o.cut_prior_weight) * p[b] + o.cut_prior_weight * pp[b];
    }
    gain[r].resize(kBins);
    for (int b = 0; b < kBins; ++b)
      gain[r][b] = static_cast<float>(
          std::clamp(std::log((p[b] + 1e-7) / (p_image[b] + 1e-7)), -o.cut_max_nats, o.cut_max_nats));
  }

  std::vector<int16_t> owner(n, -1);
  std::vector<float> best(n, -std::numeric_limits<float>::infinity());
  const float hard = 1e6f;
  for (size_t r = 0; r < organs.size(); ++r) {
    const std::string name = label_name(organs[r].id);
    std::vector<std::array<double, 3>> pts;
    for (size_t s : organs[r].seeds) pts.push_back(world(s));
    const std::vector<Segment3> tree = seed_tree(pts);
    double distance_weight = o.cut_distance_weight;
    for (int attempt = 0;; ++attempt) {
      // Box: the seeds' index box grown by margin_radii radii (in mm per axis).
      const double margin = o.cut_margin_radii * priors[r].radius_mm + o.seed_radius_mm;
      std::array<int, 3> lo{d[0], d[1], d[2]}, hi{-1, -1, -1};
      for (size_t s : organs[r].seeds) {
        const auto c = ijk(s);
        for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], c[a]), hi[a] = std::max(hi[a], c[a]);
      }
      for (int a = 0; a < 3; ++a) {
        const int m = static_cast<int>(std::ceil(margin / sp[a]));
        lo[a] = std::max(0, lo[a] - m), hi[a] = std::min(d[a] - 1, hi[a] + m);
      }
      VoxelCut cut;
      cut.dims = {hi[0] - lo[0] + 1, hi[1] - lo[1] + 1, hi[2] - lo[2] + 1};
      const size_t m = static_cast<size_t>(cut.dims[0]) * cut.dims[1] * cut.dims[2];
      cut.preference.resize(m);
      for (auto& e : cut.edge) e.assign(m, 0.0f);
      auto global = [&](size_t b) {
        const int x = static_cast<int>(b % cut.dims[0]), y = static_cast<int>((b / cut.dims[0]) % cut.dims[1]),
                  z = static_cast<int>(b / (static_cast<size_t>(cut.dims[0]) * cut.dims[1]));
        return ct.index(lo[0] + x, lo[1] + y, lo[2] + z);
      };
      const double radius = priors[r].radius_mm;
      std::vector<float> gain_box = gain[r];
      if (o.cut_background == "box") {
        std::vector<double> counts(kBins, 0.0);
        for (size_t b = 0; b < m; ++b) counts[bin_of(smooth[global(b)])] += 1;
        const std::vector<double> p_box = density(counts, h);
        for (int b = 0; b < kBins; ++b)
          gain_box[b] = static_cast<float>(std::clamp(gain[r][b] + std::log((p_image[b] + 1e-7) / (p_box[b] + 1e-7)),
                                                      -o.cut_max_nats, o.cut_max_nats));
      }
      const double area[3] = {sp[1] * sp[2], sp[0] * sp[2], sp[0] * sp[1]};
      for (size_t b = 0; b < m; ++b) {
        const size_t v = global(b);
        const double dist = distance_to(tree, world(v));
        const double unary = gain_box[bin_of(smooth[v])] - distance_weight * std::max(0.0, dist - radius) / radius;
        cut.preference[b] = static_cast<float>(unary * voxel_mm3);
        const size_t step[3] = {1, static_cast<size_t>(d[0]), static_cast<size_t>(d[0]) * d[1]};
        const int bc[3] = {static_cast<int>(b % cut.dims[0]), static_cast<int>((b / cut.dims[0]) % cut.dims[1]),
                           static_cast<int>(b / (static_cast<size_t>(cut.dims[0]) * cut.dims[1]))};
        for (int a = 0; a < 3; ++a) {
          if (bc[a] + 1 >= cut.dims[a]) continue;
          const double di = smooth[v + step[a]] - smooth[v];
          cut.edge[a][b] = static_cast<float>(o.cut_smoothness_mm * area[a] / sp[a] *
                                              std::exp(-di * di / (2 * edge_sigma * edge_sigma)));
        }
        // The box's faces inside the image are background (the organ must not reach them).
        for (int a = 0; a < 3; ++a)
          if ((bc[a] == 0 && lo[a] > 0) || (bc[a] == cut.dims[a] - 1 && hi[a] < d[a] - 1)) cut.preference[b] = -hard;
      }
      auto local = [&](size_t v) -> long {
        const auto c = ijk(v);
        for (int a = 0; a < 3; ++a)
          if (c[a] < lo[a] || c[a] > hi[a]) return -1;
        return (c[0] - lo[0]) +
               static_cast<long>(cut.dims[0]) * ((c[1] - lo[1]) + static_cast<long>(cut.dims[1]) * (c[2] - lo[2]));
      };
      for (size_t s : background)
        if (long b = local(s); b >= 0) cut.preference[b] = -hard;
      for (size_t q = 0; q < organs.size(); ++q)
        if (q != r)
          for (size_t s : organs[q].seeds)
            if (long b = local(s); b >= 0) cut.preference[b] = -hard;
      for (size_t s : organs[r].seeds)
        if (long b = local(s); b >= 0) cut.preference[b] = hard;
      const std::vector<char> inside = min_cut(cut);
      size_t count = 0;
      for (char c : inside) count += c;
      const double ml = count * voxel_mm3 / 1000.0;
      if (ml > priors[r].max_ml && attempt < 2) {
        std::fprintf(
            stderr,
            "[softatlas segment] %s: %.0f mL exceeds its bound of %.0f mL; cut again with a doubled distance prior\n",
            name.c_str(), ml, priors[r].max_ml);
        distance_weight *= 2;
        continue;
      }
      if (ml > priors[r].max_ml)
        std::fprintf(stderr,
                     "[softatlas segment] warning: %s: %.0f mL is above the plausible %.0f mL (check the seeds)\n",
                     name.c_str(), ml, priors[r].max_ml);
      std::fprintf(stderr, "[softatlas segment] %s: %zu seeds, box %dx%dx%d, %.1f mL\n", name.c_str(),
                   organs[r].seeds.size(), cut.dims[0], cut.dims[1], cut.dims[2], ml);
      for (size_t b = 0; b < m; ++b) {
        if (!inside[b]) continue;
        const size_t v = global(b);
        const float score = cut.preference[b] / static_cast<float>(voxel_mm3);
        if (score > best[v]) best[v] = score, owner[v] = static_cast<int16_t>(r);
      }
      break;
    }
  }
  return owner;
}

}  // namespace softatlas::pipeline
