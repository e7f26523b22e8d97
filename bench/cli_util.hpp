// Command-line parsing shared by the bench commands (private header).
#pragma once

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

namespace softatlas::bench {

// Parses args[skip..] with CLI11; returns -1 to continue, else the exit status (help printed: 0,
// usage error: 2).
inline int parse_args(CLI::App& app, const std::vector<std::string>& args, size_t skip) {
  std::vector<std::string> rest(args.begin() + static_cast<long>(skip), args.end());
  std::reverse(rest.begin(), rest.end());  // CLI11 takes a reversed vector
  try {
    app.parse(rest);
  } catch (const CLI::CallForHelp&) {
    std::fputs(app.help().c_str(), stdout);
    return 0;
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "softatlas: %s\n%s", e.what(), app.help().c_str());
    return 2;
  }
  return -1;
}

}  // namespace softatlas::bench
