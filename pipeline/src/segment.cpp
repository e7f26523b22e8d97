// Stage 2b, seeded segmentation without a label map.
//
// 1. Competitive region growing on the image smoothed at about the voxel size: all seed fronts
//    advance at once and each voxel goes to the front that reaches it over the lowest barrier,
//    the largest intensity step along the path (then the shortest path), as in relative fuzzy
//    connectedness (Udupa & Saha 2003); the ordered-propagation form of grow-cut (Vezhnevets &
//    Konouchine 2005). A voxel may join organ l only inside its window
//    [mu_l - 2.5 sigma_l, mu_l + 4 sigma_l], mu_l and sigma_l from the seed neighbourhoods.
//    Background seeds compete with no window; over equal barriers their paths count twice their
//    length (background_length_weight).
// 2. Vessels listed in SegmentOptions::tubes (the aorta) are replaced by a tube fitted to their
//    region (tube.hpp): unenhanced stretches filled, bone, branches and touching soft tissue cut;
//    the region is kept in a wall-wide band along the tube's sides.
// 3. Organs listed in SegmentOptions::walls (the heart) grow a wall from their region into
//    enhanced soft tissue (the myocardium), competing with the background seeds; a tube's own
//    wall is not theirs.
// 4. Per organ: closing, hole filling, opening; only the components that hold a seed are kept.
// Measurements of each step and of the alternatives tried: docs/pipeline.md.
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <queue>

#include "softatlas/pipeline/label_table.hpp"
#include "softatlas/pipeline/segment.hpp"
#include "softatlas/sim/error.hpp"
#include "grid.hpp"
#include "seeded_cut.hpp"
#include "tube.hpp"

namespace softatlas::pipeline {
namespace {

std::string mark(const std::string& path, const YAML::Node& n) {
  return path + ":" + std::to_string(n.Mark().line + 1) + ":" + std::to_string(n.Mark().column + 1);
}

std::vector<std::array<double, 3>> read_points(const std::string& path, const YAML::Node& list,
                                               const std::string& what) {
  if (!list.IsSequence()) throw InputError(mark(path, list), what + ": expected a list of [x, y, z] points");
  std::vector<std::array<double, 3>> pts;
  for (const auto& p : list) {
    if (!p.IsSequence() || p.size() != 3) throw InputError(mark(path, p), what + ": expected [x, y, z] in mm");
    std::array<double, 3> x{};
    for (int d = 0; d < 3; ++d) {
      try {
        x[d] = p[d].as<double>();
      } catch (const YAML::Exception&) {
        throw InputError(mark(path, p[d]), what + ": expected a number");
      }
      if (!std::isfinite(x[d])) throw InputError(mark(path, p[d]), what + ": expected a finite number");
    }
    pts.push_back(x);
  }
  return pts;
}

// Binary morphology on a mask (6-neighbourhood), restricted to a box for speed.
using Mask = std::vector<char>;

void dilate(Mask& m, const std::array<int, 3>& d) {
  Mask out = m;
  for (int k = 0; k < d[2]; ++k)
    for (int j = 0; j < d[1]; ++j)
      for (int i = 0; i < d[0]; ++i) {
        const size_t id = i + static_cast<size_t>(d[0]) * (j + static_cast<size_t>(d[1]) * k);
        if (m[id]) continue;
        if ((i > 0 && m[id - 1]) || (i + 1 < d[0] && m[id + 1]) || (j > 0 && m[id - d[0]]) ||
            (j + 1 < d[1] && m[id + d[0]]) || (k > 0 && m[id - static_cast<size_t>(d[0]) * d[1]]) ||
            (k + 1 < d[2] && m[id + static_cast<size_t>(d[0]) * d[1]]))
          out[id] = 1;
      }
  m.swap(out);
}

void erode(Mask& m, const std::array<int, 3>& d) {
  for (char& c : m) c = !c;
  dilate(m, d);
  for (char& c : m) c = !c;
}

// Fills cavities: voxels not reachable from the box border through non-mask voxels.
void fill_holes(Mask& m, const std::array<int, 3>& d) {
  Mask outside(m.size(), 0);
  std::vector<size_t> stack;
  auto push = [&](size_t id) {
    if (!m[id] && !outside[id]) {
      outside[id] = 1;
      stack.push_back(id);
    }
  };
  for (int k = 0; k < d[2]; ++k)
    for (int j = 0; j < d[1]; ++j)
      for (int i = 0; i < d[0]; ++i)
        if (i == 0 || j == 0 || k == 0 || i == d[0] - 1 || j == d[1] - 1 || k == d[2] - 1)
          push(i + static_cast<size_t>(d[0]) * (j + static_cast<size_t>(d[1]) * k));
  while (!stack.empty()) {
    const size_t id = stack.back();
    stack.pop_back();
    for_each_face_neighbour(d, id, [&](size_t q, int) { push(q); });
  }
  for (size_t id = 0; id < m.size(); ++id)
    if (!outside[id]) m[id] = 1;
}

// Keeps the 6-connected components of m that contain one of the seeds.
void keep_seeded(Mask& m, const std::array<int, 3>& d, const std::vector<size_t>& seeds) {
  Mask keep(m.size(), 0);
  std::vector<size_t> stack;
  for (size_t s : seeds)
    if (m[s] && !keep[s]) keep[s] = 1, stack.push_back(s);
  while (!stack.empty()) {
    const size_t id = stack.back();
    stack.pop_back();
    for_each_face_neighbour(d, id, [&](size_t q, int) {
      if (m[q] && !keep[q]) keep[q] = 1, stack.push_back(q);
    });
  }
  m.swap(keep);
}

}  // namespace

Seeds read_seeds(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw InputError(path, "cannot open the seed file");
  } catch (const YAML::Exception& e) {
    throw InputError(path + ":" + std::to_string(e.mark.line + 1) + ":" + std::to_string(e.mark.column + 1), e.msg);
  }
  if (!root.IsMap()) throw InputError(path, "expected a map with 'organs' (and optional 'background')");
  Seeds s;
  // Any yaml-cpp conversion left unchecked (a key that is a map or a sequence, `? [a]: x`, threw
  // TypedBadConversion out of the reader: libFuzzer find) becomes an error at its mark.
  try {
    for (const auto& kv : root) {
      if (!kv.first.IsScalar()) throw InputError(mark(path, kv.first), "expected a name as the key");
      const std::string key = kv.first.as<std::string>();
      if (key == "organs") {
        if (!kv.second.IsMap())
          throw InputError(mark(path, kv.second), "organs: expected a map organ: [[x, y, z], ...]");
        for (const auto& o : kv.second) {
          if (!o.first.IsScalar()) throw InputError(mark(path, o.first), "organs: expected an organ name as the key");
          const std::string name = o.first.as<std::string>();
          if (label_id(name) == 0)
            throw InputError(mark(path, o.first), "unknown organ '" + name + "' (expected a TotalSegmentator name)");
          s.organs[name] = read_points(path, o.second, name);
          if (s.organs[name].empty()) throw InputError(mark(path, o.second), name + ": expected at least one seed");
        }
      } else if (key == "background") {
        s.background = read_points(path, kv.second, "background");
      } else {
        throw InputError(mark(path, kv.first), "unknown key '" + key + "' (expected organs, background)");
      }
    }
  } catch (const YAML::Exception& e) {
    throw InputError(path + ":" + std::to_string(e.mark.line + 1) + ":" + std::to_string(e.mark.column + 1), e.msg);
  }
  if (s.organs.empty()) throw InputError(path, "no organ seeds (expected organs: {liver: [[x, y, z]], ...})");
  return s;
}

Volume segment_seeded(const Volume& ct, const Seeds& seeds, const SegmentOptions& o, const std::string& where) {
  const auto& d = ct.dims;
  const size_t n = ct.values.size();
  const std::array<double, 3> sp = spacing_mm(ct);
  struct Region {
    int id;
    double mu, sigma;
    bool window;
    double lo = 0, hi = 0;
    std::vector<size_t> seeds;
  };
  std::vector<Region> regions;
  auto seed_voxels = [&](const std::vector<std::array<double, 3>>& pts, const std::string& what) {
    std::vector<size_t> ids;
    for (const auto& p : pts) {
      const auto v = ct.voxel(p);
      const long i = std::lround(v[0]), j = std::lround(v[1]), k = std::lround(v[2]);
      if (i < 0 || j < 0 || k < 0 || i >= d[0] || j >= d[1] || k >= d[2])
        throw InputError(where + ": " + what, "seed (" + std::to_string(p[0]) + ", " + std::to_string(p[1]) + ", " +
                                                  std::to_string(p[2]) + ") mm lies outside the CT " + ct.path);
      ids.push_back(ct.index(static_cast<int>(i), static_cast<int>(j), static_cast<int>(k)));
    }
    return ids;
  };
  for (const auto& [name, pts] : seeds.organs) {
    Region r{label_id(name), 0, 0, true, 0, 0, seed_voxels(pts, name)};
    // Intensity model from the 5x5x5 neighbourhoods of all seeds together: mean and standard
    // deviation of every sampled voxel. Measured alternatives are in docs/pipeline.md (median/MAD,
    // trimmed, per-seed windows, the pooled within-neighbourhood sigma). The window reaches
    // further up than down: undiluted contrast at a caval inflow (800-900 HU) is blood too.
    double s1 = 0, s2 = 0, cnt = 0;
    for (size_t id : r.seeds) {
      const int i = static_cast<int>(id % d[0]), j = static_cast<int>((id / d[0]) % d[1]),
                k = static_cast<int>(id / (static_cast<size_t>(d[0]) * d[1]));
      for (int c = -2; c <= 2; ++c)
        for (int b = -2; b <= 2; ++b)
          for (int a = -2; a <= 2; ++a) {
            const int x = i + a, y = j + b, z = k + c;
            if (x < 0 || y < 0 || z < 0 || x >= d[0] || y >= d[1] || z >= d[2]) continue;
            const double v = ct.values[ct.index(x, y, z)];
            s1 += v, s2 += v * v, cnt += 1;
          }
    }
    r.mu = s1 / cnt;
    // Floor: CT noise; ceiling: a spread wider than soft tissue's contrast would admit fat and
    // muscle next to a vessel whose contrast fades along its length.
    r.sigma = std::clamp(std::sqrt(std::max(s2 / cnt - r.mu * r.mu, 0.0)), 20.0, o.intensity_sigma_max_hu);
    r.lo = r.mu - o.intensity_sigma_scale * r.sigma;
    r.hi = r.mu + o.intensity_sigma_scale_high * r.sigma;
    std::fprintf(stderr, "[softatlas segment] %s: %zu seeds, mean %.0f, sigma %.0f, window [%.0f, %.0f]\n",
                 name.c_str(), r.seeds.size(), r.mu, r.sigma, r.lo, r.hi);
    regions.push_back(r);
  }
  if (!seeds.background.empty())
    regions.push_back(Region{0, 0, 100.0, false, 0, 0, seed_voxels(seeds.background, "background")});

  // Growth, walls and tubes read the image smoothed at about the voxel size (CT noise of
  // 50-80 HU per voxel would otherwise decide where fronts meet).
  const double sigma[3] = {o.smoothing_mm / sp[0], o.smoothing_mm / sp[1], o.smoothing_mm / sp[2]};
  const std::vector<float> smooth = gaussian(ct.values, d, sigma);

  std::vector<int16_t> owner(n, -1);
  if (o.method == "graph_cut") {
    std::vector<CutOrgan> organs;
    std::vector<size_t> background;
    for (const auto& R : regions) {
      if (R.id != 0)
        organs.push_back({R.id, R.seeds});
      else
        background.insert(background.end(), R.seeds.begin(), R.seeds.end());
    }
    owner = seeded_cut(ct, smooth, organs, background, o);
  } else if (o.method == "growth") {
    // Ordered propagation of all fronts at once. A path's cost is its largest intensity step (in
    // bins of edge_bin_hu), then its length in mm: a voxel goes to the front that reaches it over
    // the lowest barrier, whatever the distance (relative fuzzy connectedness, Udupa & Saha 2003).
    // A plain sum of length and steps favours the nearest seed: along a 60 mm stretch of noisy
    // contrast a background click 9 mm away won it (docs/pipeline.md).
    struct Cost {
      int barrier;
      float length;
      bool operator<(const Cost& x) const { return barrier != x.barrier ? barrier < x.barrier : length < x.length; }
    };
    const Cost unreached{std::numeric_limits<int>::max(), 0.0f};
    std::vector<Cost> cost(n, unreached);
    using Item = std::pair<Cost, std::pair<size_t, int>>;
    auto later = [](const Item& x, const Item& y) { return y.first < x.first; };
    std::priority_queue<Item, std::vector<Item>, decltype(later)> heap(later);
    for (size_t r = 0; r < regions.size(); ++r)
      for (size_t s : regions[r].seeds) {
        cost[s] = Cost{0, 0.0f};
        heap.push({cost[s], {s, static_cast<int>(r)}});
      }
    while (!heap.empty()) {
      const auto [c, item] = heap.top();
      heap.pop();
      const auto [id, r] = item;
      if (owner[id] >= 0 || cost[id] < c) continue;
      owner[id] = static_cast<int16_t>(r);
      const Region& R = regions[r];
      const double vi = smooth[id];
      for_each_face_neighbour(d, id, [&, c = c, r = r](size_t q, int axis) {
        if (owner[q] >= 0) return;
        const double vq = smooth[q];
        if (R.window && (vq < R.lo || vq > R.hi)) return;
        const Cost nc{std::max(c.barrier, static_cast<int>(std::abs(vq - vi) / o.edge_bin_hu)),
                      c.length + static_cast<float>(sp[axis] * (R.id == 0 ? o.background_length_weight : 1.0))};
        if (nc < cost[q]) {
          cost[q] = nc;
          heap.push({nc, {q, r}});
        }
      });
    }
  } else {
    throw InputError("segment method", "unknown method '" + o.method + "' (expected graph_cut, growth)");
  }

  // Tubes (large vessels).
  std::vector<char> vessel_wall(n, 0);
  for (size_t r = 0; r < regions.size(); ++r) {
    if (regions[r].id == 0 || o.method != "growth" ||  // the tube and wall models belong to the growth
        std::none_of(o.tubes.begin(), o.tubes.end(),
                     [&](const std::string& t) { return label_id(t) == regions[r].id; }))
      continue;
    std::vector<char> other(n, 0);
    for (size_t id = 0; id < n; ++id)
      other[id] = owner[id] >= 0 && owner[id] != static_cast<int16_t>(r) && regions[owner[id]].id != 0;
    for (const auto& R : regions)  // a background click is never inside the tube
      if (R.id == 0)
        for (size_t s : R.seeds) other[s] = 1;
    TubeOptions to;
    to.stop_hu = o.tube_stop_hu;
    to.bright_hu = regions[r].lo + 0.5 * regions[r].sigma;
    to.lumen_min_hu = o.tube_lumen_min_hu;
    TubeReport rep;
    const std::vector<char> tube =
        vessel_tube(d, sp.data(), smooth, owner, static_cast<int>(r), other, regions[r].seeds, to, &rep);
    if (tube.empty()) {
      std::fprintf(stderr, "[softatlas segment] %s: no tube (the seeds give no centreline), region kept\n",
                   label_name(regions[r].id).c_str());
      continue;
    }
    // The vessel's own wall (wall_mm outside the tube, which is the lumen) is nobody's: another
    // organ's wall growth (the heart's myocardium at the aortic root) must not take it.
    Mask shell(n);
    for (size_t id = 0; id < n; ++id) shell[id] = tube[id] == kTubeInside;
    const int layers = std::max(1, static_cast<int>(std::lround(to.wall_mm / std::min({sp[0], sp[1], sp[2]}))));
    for (int it = 0; it < layers; ++it) dilate(shell, d);
    for (size_t id = 0; id < n; ++id)
      if (shell[id] && tube[id] != kTubeInside) vessel_wall[id] = 1;
    // The grown region is kept inside the tube and in the band along its sides: a lumen is not
    // exactly round (the arch, a bulge at a branch), and the region there is the image's own
    // outline of it. Outside the band (branches, bone, the rest of a leak) it is dropped.
    size_t kept = 0, added = 0, dropped = 0;
    for (size_t id = 0; id < n; ++id) {
      if (owner[id] == static_cast<int16_t>(r)) {
        if (tube[id] != 0)
          ++kept, vessel_wall[id] = 0;
        else
          owner[id] = -1, ++dropped;
      } else if (tube[id] == kTubeInside) {
        owner[id] = static_cast<int16_t>(r), ++added;
      }
    }
    std::fprintf(stderr,
                 "[softatlas segment] %s: tube of %zu sections, %.0f mm long, median radius %.1f mm; %zu voxels kept, "
                 "%zu added, %zu outside dropped\n",
                 label_name(regions[r].id).c_str(), rep.sections, rep.length_mm, rep.median_radius_mm, kept, added,
                 dropped);
  }

  // Walls (the heart's myocardium): a second ordered propagation by geodesic distance in mm from
  // the regions of organs with a wall, through voxels that no organ took, whose smoothed
  // intensity is at least the wall's min_hu and that lie below the organ's window (brighter
  // voxels are another structure's blood). Background seeds propagate through the same tissue,
  // so a background click in the wall stops it halfway.
  std::vector<double> wall_min(regions.size(), 0), wall_mm(regions.size(), 0), wall_hi(regions.size(), 0);
  double lowest = std::numeric_limits<double>::infinity(), widest = 0;
  for (size_t r = 0; r < regions.size(); ++r)
    for (const auto& [name, wall] : o.walls)
      if (regions[r].id != 0 && o.method == "growth" && label_id(name) == regions[r].id) {
        wall_min[r] = wall.min_hu, wall_mm[r] = wall.thickness_mm, wall_hi[r] = regions[r].lo;
        lowest = std::min(lowest, wall_min[r]), widest = std::max(widest, wall_mm[r]);
      }
  if (widest > 0) {  // some seeded organ has a wall
    for (size_t r = 0; r < regions.size(); ++r)
      if (regions[r].id == 0)
        wall_min[r] = lowest, wall_mm[r] = widest, wall_hi[r] = std::numeric_limits<double>::infinity();
    auto is_organ = [&](size_t id) { return owner[id] >= 0 && regions[owner[id]].id != 0; };
    std::vector<float> dist(n, std::numeric_limits<float>::infinity());
    std::vector<int16_t> front(n, -1);
    using WallItem = std::pair<float, std::pair<size_t, int>>;
    std::priority_queue<WallItem, std::vector<WallItem>, std::greater<WallItem>> walls;
    for (size_t id = 0; id < n; ++id)
      if (is_organ(id) && wall_mm[owner[id]] > 0) dist[id] = 0, walls.push({0.0f, {id, owner[id]}});
    for (size_t r = 0; r < regions.size(); ++r)
      if (regions[r].id == 0)
        for (size_t s : regions[r].seeds) dist[s] = 0, walls.push({0.0f, {s, static_cast<int>(r)}});
    while (!walls.empty()) {
      const auto [c, item] = walls.top();
      walls.pop();
      const auto [id, r] = item;
      if (front[id] >= 0 || c > dist[id]) continue;
      front[id] = static_cast<int16_t>(r);
      for_each_face_neighbour(d, id, [&, c = c, r = r](size_t q, int axis) {
        if (front[q] >= 0 || is_organ(q) || vessel_wall[q]) return;
        if (smooth[q] < wall_min[r] || ct.values[q] >= wall_hi[r]) return;
        const float nd = static_cast<float>(c + sp[axis]);
        if (nd > wall_mm[r] || nd >= dist[q]) return;
        dist[q] = nd;
        walls.push({nd, {q, r}});
      });
    }
    size_t grown = 0;
    for (size_t id = 0; id < n; ++id)
      if (front[id] >= 0 && regions[front[id]].id != 0 && !is_organ(id)) owner[id] = front[id], ++grown;
    std::fprintf(stderr, "[softatlas segment] walls: %zu voxels added\n", grown);
  }

  Volume out;
  out.dims = ct.dims;
  out.ijk_to_ras = ct.ijk_to_ras;
  out.path = where;
  out.format = "nifti";
  out.values.assign(n, 0.0f);
  for (size_t r = 0; r < regions.size(); ++r) {
    if (regions[r].id == 0) continue;
    Mask m(n, 0);
    for (size_t id = 0; id < n; ++id) m[id] = owner[id] == static_cast<int16_t>(r);
    for (int it = 0; it < o.closing_radius; ++it) dilate(m, d);
    for (int it = 0; it < o.closing_radius; ++it) erode(m, d);
    fill_holes(m, d);
    for (int it = 0; it < o.closing_radius; ++it) erode(m, d);
    for (int it = 0; it < o.closing_radius; ++it) dilate(m, d);
    // Seeds may sit in a voxel the opening removed; keep components reached from any seed's
    // surroundings by growing from the seeds themselves where they survived.
    keep_seeded(m, d, regions[r].seeds);
    for (size_t id = 0; id < n; ++id)
      if (m[id] && out.values[id] == 0.0f) out.values[id] = static_cast<float>(regions[r].id);
  }
  return out;
}

double dice(const Volume& a, int id_a, const Volume& b, int id_b) {
  if (a.values.size() != b.values.size()) throw InputError(b.path, "Dice needs two volumes on the same grid");
  size_t na = 0, nb = 0, both = 0;
  for (size_t i = 0; i < a.values.size(); ++i) {
    const bool x = std::lround(a.values[i]) == id_a, y = std::lround(b.values[i]) == id_b;
    na += x, nb += y, both += x && y;
  }
  return na + nb ? 2.0 * static_cast<double>(both) / static_cast<double>(na + nb) : 1.0;
}

}  // namespace softatlas::pipeline
