// Small helpers that read yaml-cpp nodes and turn every problem into an InputError with
// FILE:LINE:COLUMN (yaml-cpp marks are 0-based; editors count from 1).
#pragma once

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <initializer_list>
#include <set>
#include <string>
#include <vector>

#include "softatlas/sim/error.hpp"

namespace softatlas::app::yamlcheck {

struct Ctx {
  std::string file;
  std::string at(const YAML::Node& n) const {
    const YAML::Mark m = n.Mark();
    if (m.line < 0) return file;
    return file + ":" + std::to_string(m.line + 1) + ":" + std::to_string(m.column + 1);
  }
  [[noreturn]] void fail(const YAML::Node& n, const std::string& what) const { throw InputError(at(n), what); }

  void expect_map(const YAML::Node& n, const std::string& name) const {
    if (!n.IsMap()) fail(n, "'" + name + "' must be a map (key: value lines)");
  }
  // Unknown keys: one error naming the key and the keys that are allowed.
  void keys(const YAML::Node& map, const std::string& name, std::initializer_list<const char*> allowed) const {
    expect_map(map, name);
    for (const auto& kv : map) {
      const std::string key = kv.first.Scalar();
      bool ok = false;
      for (const char* a : allowed) ok = ok || key == a;
      if (!ok) {
        std::string list;
        for (const char* a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
        fail(kv.first, "unknown key '" + key + "' in " + name + " (expected one of: " + list + ")");
      }
    }
  }
  YAML::Node require(const YAML::Node& map, const char* key, const std::string& name) const {
    const YAML::Node n = map[key];
    if (!n) fail(map, name + " needs '" + key + "'");
    return n;
  }
  std::string str(const YAML::Node& n, const std::string& name) const {
    if (!n.IsScalar()) fail(n, "'" + name + "' must be a text value");
    return n.Scalar();
  }
  double num(const YAML::Node& n, const std::string& name, double lo, double hi) const {
    if (!n.IsScalar()) fail(n, "'" + name + "' must be a number");
    double v = 0;
    try {
      size_t used = 0;
      v = std::stod(n.Scalar(), &used);
      if (used != n.Scalar().size()) throw std::invalid_argument("trailing");
    } catch (const std::exception&) {
      fail(n, "'" + name + "' must be a number, got '" + n.Scalar() + "'");
    }
    if (!std::isfinite(v) || v < lo || v > hi)
      fail(n, "'" + name + "' must be in [" + fmt(lo) + ", " + fmt(hi) + "], got " + n.Scalar());
    return v;
  }
  bool boolean(const YAML::Node& n, const std::string& name) const {
    if (!n.IsScalar()) fail(n, "'" + name + "' must be true or false");
    const std::string& s = n.Scalar();
    if (s == "true" || s == "yes" || s == "on") return true;
    if (s == "false" || s == "no" || s == "off") return false;
    fail(n, "'" + name + "' must be true or false, got '" + s + "'");
  }
  std::vector<double> vec(const YAML::Node& n, const std::string& name, size_t count, double lo, double hi) const {
    if (!n.IsSequence() || n.size() != count)
      fail(n, "'" + name + "' must be a list of " + std::to_string(count) + " numbers, e.g. [0, 0, -10]");
    std::vector<double> out;
    for (const auto& e : n) out.push_back(num(e, name, lo, hi));
    return out;
  }
  // A name or a list of names.
  std::vector<std::string> names(const YAML::Node& n, const std::string& name) const {
    std::vector<std::string> out;
    if (n.IsScalar()) out.push_back(n.Scalar());
    else if (n.IsSequence()) {
      for (const auto& e : n) out.push_back(str(e, name));
    } else fail(n, "'" + name + "' must be an organ name or a list of organ names");
    if (out.empty()) fail(n, "'" + name + "' must name at least one organ");
    return out;
  }
  static std::string fmt(double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%g", v);
    return b;
  }
};

// Parses a file; yaml-cpp syntax errors become FILE:LINE:COLUMN: message too.
inline YAML::Node load_file(const std::string& path, const std::string& text) {
  try {
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw InputError(path + ":" + std::to_string(e.mark.line + 1) + ":" + std::to_string(e.mark.column + 1),
                     "YAML syntax: " + e.msg);
  }
}

}  // namespace softatlas::app::yamlcheck
