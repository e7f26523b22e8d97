// InputError: the one exception type for bad input anywhere in SoftAtlas.
//
// It carries where the problem is (a file, and a line/column or a field) and what was expected.
// The top of `softatlas` turns it into one readable line and a non-zero exit. The physics step
// never throws; only compilers and readers do.
#pragma once

#include <stdexcept>
#include <string>

namespace softatlas {

class InputError : public std::runtime_error {
 public:
  // where: "file", "file:line", "file:line:column" or "file: field"; what: the problem and what
  // was expected ("expected a positive number, got -3").
  InputError(std::string where, std::string what)
      : std::runtime_error(where.empty() ? what : where + ": " + what),
        where_(std::move(where)),
        what_(std::move(what)) {}

  const std::string& where() const noexcept { return where_; }
  const std::string& problem() const noexcept { return what_; }

 private:
  std::string where_;
  std::string what_;
};

}  // namespace softatlas
