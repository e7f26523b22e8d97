// One command line (issue 17): every `softatlas` subcommand is a CLI11 subcommand registered on
// one CLI::App by the library that owns it (pipeline, app, bench, evidence), and one function
// parses and runs it, with one exit convention for all of them:
//   0 ok, 1 bad input (an InputError: one line naming the file or option), 2 usage error (an
//   unknown command or option, a missing or out-of-range value), and 3 for `lesson run` when a
//   task of the lesson failed (an outcome, not an error).
// Header-only: include it where CLI11 is linked.
#pragma once

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "softatlas/io/mesh_io.hpp"

namespace softatlas::cli {

constexpr int kOk = 0;
constexpr int kBadInput = 1;
constexpr int kUsageError = 2;

// The status the subcommand that ran returned (set by its callback during parsing).
struct Status {
  int rc = kOk;
};

// The subcommand `name` of `parent`, added (requiring one subcommand of its own) if it is not
// there yet: `bench` and `lesson` are groups several libraries add to.
inline CLI::App* group(CLI::App& parent, const std::string& name, const std::string& about) {
  for (CLI::App* s : parent.get_subcommands([](CLI::App*) { return true; }))
    if (s->get_name() == name) return s;
  CLI::App* g = parent.add_subcommand(name, about);
  g->require_subcommand(1);
  return g;
}

// Makes `run` the body of the subcommand `app`: it runs after the whole command line parsed and
// its return value becomes the exit status.
inline void on_run(CLI::App* app, Status* status, std::function<int()> run) {
  app->callback([status, run = std::move(run)] { status->rc = run(); });
}

// The words of the deepest subcommand chosen on the command line ("bench sim").
inline std::string chosen_path(const CLI::App& root) {
  std::string path;
  const CLI::App* at = &root;
  for (;;) {
    const auto chosen = at->get_subcommands();
    if (chosen.empty()) break;
    at = chosen.front();
    path += (path.empty() ? "" : " ") + at->get_name();
  }
  return path;
}

// Parses args (without the program name) with root and runs the chosen subcommand. --help prints
// the chosen subcommand's options on stdout (status 0); a usage error prints one line and a hint
// on stderr (status 2). An InputError from the subcommand propagates (main prints it, status 1).
inline int run(CLI::App& root, const Status& status, const std::vector<std::string>& args) {
  std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11 takes a reversed vector
  try {
    root.parse(reversed);
  } catch (const CLI::CallForHelp&) {
    std::fputs(root.help().c_str(), stdout);
    return kOk;
  } catch (const CLI::ParseError& e) {
    const std::string path = chosen_path(root);
    const std::string where = path.empty() ? "" : path + ": ";
    std::fprintf(stderr, "softatlas: %s%s\nRun 'softatlas %s%s--help' for the options.\n", where.c_str(),
                 io::printable_text(e.what(), 600).c_str(), path.c_str(), path.empty() ? "" : " ");
    return kUsageError;
  }
  return status.rc;
}

// The cli_main of one library: a root with only that library's subcommands (`add`), parsed and run.
inline int run_only(void (*add)(CLI::App&, Status*), const std::vector<std::string>& args) {
  CLI::App root{"softatlas", "softatlas"};
  root.require_subcommand(1);
  Status status;
  add(root, &status);
  return run(root, status, args);
}

}  // namespace softatlas::cli
