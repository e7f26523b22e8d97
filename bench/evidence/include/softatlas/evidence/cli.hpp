// `softatlas bench accuracy|stability [--quick] --out DIR` (issue 7), registered on the one command
// line (softatlas/io/cli.hpp).
#pragma once

#include <string>
#include <vector>

namespace CLI {
class App;
}
namespace softatlas::cli {
struct Status;
}

namespace softatlas::evidence {

// Adds bench accuracy and bench stability to root's `bench` group.
void add_commands(CLI::App& root, cli::Status* status);

// args: the whole argument list after `softatlas`, e.g. {"bench", "accuracy", "--quick", "--out", "DIR"}.
// Writes DIR/results.json and SVG plots; prints a one-line JSON summary on stdout and progress on
// stderr. Returns the exit status (0 ok, 2 usage error); throws InputError for bad input.
int cli_main(const std::vector<std::string>& args);

}  // namespace softatlas::evidence
