// Errors that ldem reports to its user.
#pragma once

#include <stdexcept>
#include <string>

namespace ldem {

// Bad input: a case, a command-line value or a request the model cannot honour.
// The message says what was expected and what was found.
class InputError : public std::runtime_error {
public:
  explicit InputError(const std::string& what) : std::runtime_error(what) {}
};

} // namespace ldem
