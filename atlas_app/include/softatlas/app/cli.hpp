// `softatlas view | lesson | bench render | bench haptic`: args is the whole argument list
// after `softatlas` (args[0] is the command). Returns the process exit status; bad input
// throws InputError (one line, exit 1, printed by the softatlas main).
#pragma once

#include <string>
#include <vector>

namespace softatlas::app {

int cli_main(const std::vector<std::string>& args);

}  // namespace softatlas::app
