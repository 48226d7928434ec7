// fmt, for the units that import peridot.std (see CMakeLists.txt).
module;
#include <fmt/core.h>
export module peridot.std:fmt;

export namespace fmt {
using fmt::format;
using fmt::format_string;
using fmt::print;
using fmt::runtime;
}  // namespace fmt
