// The error type of magnav: every function that reads outside data (files,
// flags, option structs, DDS samples) reports a problem by throwing InputError
// whose message names the place (file:line, column, field or option).
#pragma once

#include <stdexcept>
#include <string>

namespace magnav {

class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace magnav
