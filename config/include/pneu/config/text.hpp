// printf into a std::string, for the lines and fields the programs write (not on the loop thread:
// it allocates).
#pragma once

#include <cstdarg>
#include <string>

namespace pneu::text {

/// The text printf would print, whole, however long.
[[gnu::format(printf, 1, 2)]] std::string format(const char* format, ...);
/// The same, from a variadic function's arguments (for one that takes a format of its own).
[[gnu::format(printf, 1, 0)]] std::string vformat(const char* format, va_list args);

}  // namespace pneu::text
