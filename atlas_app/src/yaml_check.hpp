// Small helpers that read yaml-cpp nodes and collect every problem as FILE:LINE:COLUMN: message
// (yaml-cpp marks are 0-based; editors count from 1), so one `lesson check` run reports all of
// them in file order.
//
// yaml-cpp is lenient where a lesson author needs strictness; Ctx adds:
//  - strict_scan(): a quoted scalar must close on the line it opens (an unterminated quote is
//    reported where it starts, instead of swallowing the next lines into the text);
//  - keys(): duplicate keys are errors (yaml-cpp keeps both and returns the first);
//  - str()/num(): plain `42`, `true` or `null` where text is expected, and quoted "12" where a
//    number is expected, are type errors.
#pragma once

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <initializer_list>
#include <map>
#include <string>
#include <vector>

#include "softatlas/sim/error.hpp"

namespace softatlas::app::yamlcheck {

struct Diag {
  int line = 0, column = 0;  // 1-based; 0 = whole file
  std::string message;
};

// Thrown by Ctx::fail after recording: abandons the node being read (the caller's guard()
// catches it and goes on with the next field or step).
struct Skip {};

// Every error of one file, in file order. what() is all of them, one FILE:LINE:COLUMN: message
// line each; where()/problem() are the first.
class CheckErrors : public InputError {
 public:
  CheckErrors(const std::string& file, std::vector<Diag> diags)
      : InputError(location(file, diags.at(0)), join(file, diags)), file_(file), diags_(std::move(diags)) {}
  const std::vector<Diag>& diagnostics() const { return diags_; }
  std::vector<std::string> lines() const {
    std::vector<std::string> out;
    for (const Diag& d : diags_) out.push_back(location(file_, d) + ": " + d.message);
    return out;
  }
  static std::string location(const std::string& file, const Diag& d) {
    return d.line <= 0 ? file : file + ":" + std::to_string(d.line) + ":" + std::to_string(d.column);
  }

 private:
  static std::string join(const std::string& file, const std::vector<Diag>& d) {
    std::string s = d[0].message;
    for (size_t i = 1; i < d.size(); ++i) s += "\n" + location(file, d[i]) + ": " + d[i].message;
    return s;
  }
  std::string file_;
  std::vector<Diag> diags_;
};

struct Ctx {
  std::string file;
  mutable std::vector<Diag> errors;

  static Diag diag(const YAML::Node& n, const std::string& what) {
    const YAML::Mark m = n.Mark();
    if (m.line < 0) return {0, 0, what};
    return {m.line + 1, m.column + 1, what};
  }
  std::string at(const YAML::Node& n) const { return CheckErrors::location(file, diag(n, "")); }
  void report(const YAML::Node& n, const std::string& what) const { errors.push_back(diag(n, what)); }
  void report_at(int line, int column, const std::string& what) const { errors.push_back({line, column, what}); }
  [[noreturn]] void fail(const YAML::Node& n, const std::string& what) const {
    report(n, what);
    throw Skip{};
  }
  // Runs f; a fail() inside only abandons f. A yaml-cpp exception (a node of an unexpected kind
  // read as another) becomes an error at its mark, never an escape (found by fuzz_lesson).
  template <class F>
  void guard(F&& f) const {
    try {
      f();
    } catch (const Skip&) {
    } catch (const YAML::Exception& e) {
      report_at(std::max(1, e.mark.line + 1), std::max(1, e.mark.column + 1),
                "unexpected YAML structure here (" + e.msg + ")");
    }
  }
  // Throws CheckErrors with every recorded error, sorted by line and column (stable).
  void finish() const {
    if (errors.empty()) return;
    std::vector<Diag> d = errors;
    std::stable_sort(d.begin(), d.end(), [](const Diag& a, const Diag& b) {
      return a.line != b.line ? a.line < b.line : a.column < b.column;
    });
    throw CheckErrors(file, std::move(d));
  }

  void expect_map(const YAML::Node& n, const std::string& name) const {
    if (!n.IsMap()) fail(n, "'" + name + "' must be a map (key: value lines)");
  }
  // Unknown and duplicate keys: one error each (the node stays readable).
  void keys(const YAML::Node& map, const std::string& name, std::initializer_list<const char*> allowed) const {
    expect_map(map, name);
    std::map<std::string, int> seen;
    for (const auto& kv : map) {
      if (!kv.first.IsScalar()) {
        report(kv.first, "keys in " + name + " must be plain words");
        continue;
      }
      const std::string key = kv.first.Scalar();
      const auto [it, fresh] = seen.emplace(key, kv.first.Mark().line + 1);
      if (!fresh) {
        report(kv.first,
               "duplicate key '" + key + "' in " + name + " (first given on line " + std::to_string(it->second) + ")");
        continue;
      }
      bool ok = false;
      for (const char* a : allowed) ok = ok || key == a;
      if (!ok) {
        std::string list;
        for (const char* a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
        report(kv.first, "unknown key '" + key + "' in " + name + " (expected one of: " + list + ")");
      }
    }
  }
  YAML::Node require(const YAML::Node& map, const char* key, const std::string& name) const {
    const YAML::Node n = map[key];
    if (!n) fail(map, name + " needs '" + key + "'");
    return n;
  }
  // A plain scalar that YAML would read as a number, true/false or null.
  static bool looks_typed(const YAML::Node& n) {
    if (n.Tag() != "?") return false;  // quoted: text
    const std::string& s = n.Scalar();
    static const char* words[] = {"true", "false", "True", "False", "TRUE", "FALSE", "yes", "no",
                                  "on",   "off",   "null", "Null",  "NULL", "~",     ""};
    for (const char* w : words)
      if (s == w) return true;
    return is_number(s);
  }
  static bool is_number(const std::string& s) {
    if (s.empty()) return false;
    try {
      size_t used = 0;
      (void)std::stod(s, &used);
      return used == s.size();
    } catch (const std::exception&) {
      return false;
    }
  }
  std::string str(const YAML::Node& n, const std::string& name) const {
    if (!n.IsScalar()) fail(n, "'" + name + "' must be a text value");
    if (looks_typed(n))
      fail(n, "'" + name + "' must be text, got " + (is_number(n.Scalar()) ? "the number " : "the value ") +
                  (n.Scalar().empty() ? "null" : n.Scalar()) + " (put it in quotes if you mean the text)");
    return n.Scalar();
  }
  double num(const YAML::Node& n, const std::string& name, double lo, double hi) const {
    if (!n.IsScalar()) fail(n, "'" + name + "' must be a number");
    if (n.Tag() != "?")
      fail(n, "'" + name + "' must be a number, got the text \"" + n.Scalar() + "\" (remove the quotes)");
    if (!is_number(n.Scalar())) fail(n, "'" + name + "' must be a number, got '" + n.Scalar() + "'");
    const double v = std::stod(n.Scalar());
    if (!std::isfinite(v) || v < lo || v > hi)
      fail(n, "'" + name + "' must be in [" + fmt(lo) + ", " + fmt(hi) + "], got " + n.Scalar());
    return v;
  }
  bool boolean(const YAML::Node& n, const std::string& name) const {
    if (!n.IsScalar() || n.Tag() != "?") fail(n, "'" + name + "' must be true or false");
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
    if (n.IsScalar())
      out.push_back(str(n, name));
    else if (n.IsSequence()) {
      for (const auto& e : n) guard([&] { out.push_back(str(e, name)); });
    } else
      fail(n, "'" + name + "' must be an organ name or a list of organ names");
    if (out.empty() && n.IsSequence() && n.size() == 0) fail(n, "'" + name + "' must name at least one organ");
    return out;
  }
  static std::string fmt(double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%g", v);
    return b;
  }
};

// The strict pre-scan (see the top of this file): a quote that opens a scalar must close on the
// same line. Long text goes in a block scalar (`say: >` and indented lines), whose lines are
// skipped here. Returns whether the text is clean.
inline bool strict_scan(const Ctx& c, const std::string& text) {
  bool clean = true;
  int line = 0;
  int block_indent = -1;  // inside a block scalar: lines indented more than this belong to it
  size_t pos = 0;
  while (pos <= text.size()) {
    size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    const std::string l = text.substr(pos, end - pos);
    ++line;
    pos = end + 1;
    const size_t first = l.find_first_not_of(' ');
    const int indent = first == std::string::npos ? -1 : static_cast<int>(first);
    if (block_indent >= 0) {
      if (indent < 0 || indent > block_indent) continue;
      block_indent = -1;
    }
    if (indent < 0) continue;
    bool token_start = true;  // a quote opens a scalar only where a value can begin
    char last_sig = ' ';
    for (size_t i = first; i < l.size(); ++i) {
      const char ch = l[i];
      if (ch == '#' && (i == 0 || l[i - 1] == ' ')) break;
      if ((ch == '"' || ch == '\'') && token_start) {
        size_t j = i + 1;
        bool closed = false;
        for (; j < l.size(); ++j) {
          if (ch == '"' && l[j] == '\\') {
            ++j;
            continue;
          }
          if (l[j] == ch) {
            if (ch == '\'' && j + 1 < l.size() && l[j + 1] == '\'') {
              ++j;
              continue;
            }
            closed = true;
            break;
          }
        }
        if (!closed) {
          c.report_at(line, static_cast<int>(i) + 1,
                      std::string("unterminated quote: the text opened by ") + ch +
                          " here does not close on this line (close it, or write long text as a block: 'say: >' "
                          "then indented lines)");
          clean = false;
          break;
        }
        i = j;
        token_start = false;
        last_sig = ch;
        continue;
      }
      if (ch == ' ') {
        if (last_sig == ':' || last_sig == '-' || last_sig == ',' || last_sig == '[' || last_sig == '{' ||
            last_sig == '?')
          token_start = true;
        continue;
      }
      token_start = ch == '[' || ch == '{' || ch == ',';
      last_sig = ch;
    }
    // A block scalar indicator at the end of the line: `key: |`, `key: >-`, `- >`.
    std::string t = l;
    const size_t hash = t.find(" #");
    if (hash != std::string::npos) t = t.substr(0, hash);
    while (!t.empty() && t.back() == ' ') t.pop_back();
    for (const char* ind : {": |", ": >", ": |-", ": >-", ": |+", ": >+", "- |", "- >", "- |-", "- >-"}) {
      const std::string s(ind);
      if (t.size() >= s.size() && t.compare(t.size() - s.size(), s.size(), s) == 0) block_indent = indent;
    }
  }
  return clean;
}

// Parses a file strictly (see strict_scan); problems are recorded in c. Returns a null node when
// the file cannot be read further (syntax errors).
inline YAML::Node load_file(const Ctx& c, const std::string& text) {
  const bool clean = strict_scan(c, text);
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    c.report_at(e.mark.line + 1, e.mark.column + 1, "YAML syntax: " + e.msg);
    return YAML::Node();
  }
  return clean ? root : YAML::Node();
}

}  // namespace softatlas::app::yamlcheck
