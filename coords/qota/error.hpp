// qota's single error type. Every failure the library can report (bad input, unreadable or
// unwritable files, resource limits) is thrown as qota::Error with a message that names the file,
// line, polygon or value at fault. Tools catch it, print the message and exit non-zero.
#pragma once

#include <stdexcept>
#include <string>

namespace qota {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace qota
