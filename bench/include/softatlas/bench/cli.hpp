// `softatlas bench sim` and `softatlas sim --explain`.
#pragma once

#include <string>
#include <vector>

namespace softatlas::bench {
int cli_main(const std::vector<std::string>& args);
}
