// `softatlas build --config build.yaml`: the build settings file (pipeline/include/.../build.hpp).
// Its own source so that the fuzz target build_yaml links it without the pipeline (fuzz/).
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdlib>
#include <sstream>
#include <string>

#include "softatlas/pipeline/build.hpp"
#include "softatlas/sim/error.hpp"

namespace softatlas::pipeline {

void apply_build_config(const std::string& path, BuildOptions* o) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw InputError(path, "cannot open the build config");
  } catch (const YAML::Exception& e) {
    throw InputError(path + ":" + std::to_string(e.mark.line + 1) + ":" + std::to_string(e.mark.column + 1), e.msg);
  }
  if (!root.IsMap()) throw InputError(path, "expected a YAML map of build settings");
  auto where = [&](const YAML::Node& n, const std::string& key) {
    return path + ":" + std::to_string(n.Mark().line + 1) + ":" + std::to_string(n.Mark().column + 1) + ": " + key;
  };
  // Every number a finite plain scalar within its range, counts whole (a count of 1e300 or nan was
  // cast to int: undefined behaviour that UBSan reports); any yaml-cpp conversion of a node of
  // another kind (a map as a key or an organ name) becomes an error at its mark.
  auto num = [&](const YAML::Node& n, const std::string& key, double lo, double hi) {
    if (!n.IsScalar()) throw InputError(where(n, key), "expected a number");
    const std::string& text = n.Scalar();
    char* end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(v))
      throw InputError(where(n, key), "expected a finite number");
    if (v < lo || v > hi) {
      std::ostringstream range;
      range << "expected a number in [" << lo << ", " << hi << "]";
      throw InputError(where(n, key), range.str());
    }
    return v;
  };
  auto count = [&](const YAML::Node& n, const std::string& key, double lo, double hi) {
    const double v = num(n, key, lo, hi);
    if (v != std::floor(v)) throw InputError(where(n, key), "expected a whole number");
    return static_cast<int>(v);
  };
  auto name = [&](const YAML::Node& n, const std::string& key) {
    if (!n.IsScalar()) throw InputError(where(n, key), "expected a name");
    return n.Scalar();
  };
  try {
    for (const auto& kv : root) {
      const std::string key = name(kv.first, "key");
      const YAML::Node& v = kv.second;
      if (key == "organs") {
        if (!v.IsSequence()) throw InputError(where(v, key), "expected a list of organ names");
        for (const auto& n : v) o->organs.push_back(name(n, key));
      } else if (key == "budget" || key == "budgets") {
        if (!v.IsMap()) throw InputError(where(v, key), "expected a map organ: faces");
        for (const auto& b : v) o->budgets[name(b.first, key)] = count(b.second, key, 4, 5e7);
      } else if (key == "smoothing_iterations") {
        o->surface.smoothing_iterations = count(v, key, 0, 1000);
      } else if (key == "smoothing_passband") {
        o->surface.smoothing_passband = num(v, key, 0.001, 2);
      } else if (key == "speck_share") {
        o->surface.speck_share = num(v, key, 0, 1);
      } else if (key == "remesh_iterations") {
        o->remesh.remesh_iterations = count(v, key, 0, 100);
      } else if (key == "wrap_alpha_mm") {
        o->remesh.wrap_alpha_mm = num(v, key, 0, 1000);
      } else if (key == "connect_distance_mm") {
        o->connect.distance_mm = num(v, key, 0, 1000);
      } else if (key == "connect_spacing_mm") {
        o->connect.spacing_mm = num(v, key, 0, 1000);
      } else if (key == "connect_stiffness") {
        o->connect.stiffness = num(v, key, 0, 1e6);
      } else if (key == "anchor_count") {
        o->connect.anchor_count = count(v, key, 0, 1000);
      } else if (key == "anchor_spacing_mm") {
        o->connect.anchor_spacing_mm = num(v, key, 0, 1000);
      } else if (key == "connect_pairs") {
        if (!v.IsSequence()) throw InputError(where(v, key), "expected a list of [organ_a, organ_b]");
        o->connect.pairs.clear();
        for (const auto& p : v) {
          if (!p.IsSequence() || p.size() != 2) throw InputError(where(p, key), "expected [organ_a, organ_b]");
          o->connect.pairs.emplace_back(name(p[0], key), name(p[1], key));
        }
      } else {
        throw InputError(where(kv.first, key),
                         "unknown key (expected organs, budget, smoothing_iterations, smoothing_passband, "
                         "speck_share, remesh_iterations, wrap_alpha_mm, connect_distance_mm, "
                         "connect_spacing_mm, connect_stiffness, connect_pairs, anchor_count, anchor_spacing_mm)");
      }
    }
  } catch (const YAML::Exception& e) {
    throw InputError(path + ":" + std::to_string(e.mark.line + 1) + ":" + std::to_string(e.mark.column + 1), e.msg);
  }
}

}  // namespace softatlas::pipeline
