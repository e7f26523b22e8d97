// `softatlas view | lesson check | lesson run | bench render | bench haptic`, registered on the one
// command line (softatlas/io/cli.hpp).
#pragma once

#include <string>
#include <vector>

namespace CLI {
class App;
}
namespace softatlas::cli {
struct Status;
}

namespace softatlas::app {

// Adds the app's subcommands to root (the `bench` and `lesson` groups are shared).
void add_commands(CLI::App& root, cli::Status* status);

// Parses and runs the whole argument list after `softatlas` (args[0] is the command) with only
// the app's commands. Returns the exit status (0 ok, 2 usage error, 3 lesson failed); bad input
// throws InputError (one line, exit 1, printed by the softatlas main).
int cli_main(const std::vector<std::string>& args);

}  // namespace softatlas::app
