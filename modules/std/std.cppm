// The standard library names Peridot's modules use, exported from one module unit (see
// CMakeLists.txt). A name missing here is an error in the unit that uses it: add it here.
module;
#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <climits>
#include <cmath>
#include <compare>
#include <concepts>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <new>
#include <numbers>
#include <numeric>
#include <optional>
#include <random>
#include <ranges>
#include <set>
#include <span>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <thread>
#include <tuple>
#include <type_traits>
#include <unordered_map>
#include <utility>
#include <variant>
#include <vector>
export module peridot.std;
export import :fmt;

export namespace std {
// Inside an inline namespace: a libstdc++ class template that befriends one of these
// functions (set befriends operator==, shared_ptr make_shared) would otherwise find the
// using-declaration where it looks for the function, which clang rejects.
inline namespace peridot_exports {
// Operators and what structured bindings, range-for and hashing find by argument-dependent lookup.
using std::operator==;
using std::operator!=;
using std::operator<;
using std::operator>;
using std::operator<=;
using std::operator>=;
using std::operator<=>;
using std::operator+;
using std::operator-;
using std::operator|;
using std::operator&;
using std::operator^;
using std::operator~;
using std::operator|=;
using std::operator&=;
using std::operator<<;
using std::operator>>;
using std::begin;
using std::end;
using std::data;
using std::empty;
using std::get;
using std::hash;
using std::size;
using std::swap;
using std::tuple_element;
using std::tuple_size;

// Types.
using std::array;
using std::atomic;
using std::bad_alloc;
using std::basic_string;
using std::char_traits;
using std::allocator;
using std::condition_variable;
using std::errc;
using std::error_code;
using std::exception;
using std::exception_ptr;
using std::FILE;
using std::function;
using std::ifstream;
using std::initializer_list;
using std::int16_t;
using std::int32_t;
using std::int64_t;
using std::integral_constant;
using std::invalid_argument;
using std::ios;
using std::istreambuf_iterator;
using std::length_error;
using std::lock_guard;
using std::logic_error;
using std::map;
using std::memory_order_relaxed;
using std::mt19937_64;
using std::mutex;
using std::nullopt;
using std::nullopt_t;
using std::numeric_limits;
using std::ofstream;
using std::once_flag;
using std::optional;
using std::out_of_range;
using std::pair;
using std::ptrdiff_t;
using std::runtime_error;
using std::set;
using std::shared_ptr;
using std::size_t;
using std::span;
using std::streamsize;
using std::string;
using std::string_view;
using std::stringstream;
using std::ostringstream;
using std::istringstream;
using std::thread;
using std::tuple;
using std::uint16_t;
using std::uint32_t;
using std::uint64_t;
using std::uint8_t;
using std::uniform_real_distribution;
using std::unique_lock;
using std::unique_ptr;
using std::unordered_map;
using std::variant;
using std::vector;
using std::weak_ptr;
using std::default_delete;
using std::greater_equal;
using std::less;
using std::equal_to;
using std::plus;

// Traits and concepts.
using std::conditional_t;
using std::convertible_to;
using std::decay_t;
using std::declval;
using std::integral;
using std::floating_point;
using std::invocable;
using std::is_floating_point_v;
using std::is_integral_v;
using std::is_invocable_v;
using std::is_same_v;
using std::is_trivially_copyable_v;
using std::remove_const_t;
using std::remove_cvref_t;
using std::remove_reference_t;
using std::same_as;
using std::true_type;
using std::bool_constant;
using std::false_type;
using std::enable_if_t;
using std::invoke_result_t;

// Functions.
using std::abort;
using std::abs;
using std::accumulate;
using std::adjacent_find;
using std::aligned_alloc;
using std::all_of;
using std::any_of;
using std::asin;
using std::atan2;
using std::atoi;
using std::atoll;
using std::back_inserter;
using std::call_once;
using std::ceil;
using std::clamp;
using std::copy;
using std::bit_cast;
using std::copy_n;
using std::cos;
using std::count;
using std::count_if;
using std::current_exception;
using std::erase_if;
using std::exchange;
using std::exp;
using std::frexp;
using std::ldexp;
using std::ilogb;
using std::fclose;
using std::fflush;
using std::fill;
using std::fill_n;
using std::find;
using std::find_if;
using std::floor;
using std::fopen;
using std::forward;
using std::fprintf;
using std::fread;
using std::free;
using std::from_chars;
using std::get_if;
using std::getenv;
using std::getline;
using std::holds_alternative;
using std::hypot;
using std::iota;
using std::is_sorted;
using std::isalnum;
using std::isalpha;
using std::isdigit;
using std::isfinite;
using std::isinf;
using std::isnan;
using std::isspace;
using std::llabs;
using std::log;
using std::log10;
using std::lower_bound;
using std::binary_search;
using std::lround;
using std::llround;
using std::make_pair;
using std::make_shared;
using std::make_unique;
using std::max;
using std::max_element;
using std::memcmp;
using std::memcpy;
using std::memset;
using std::min;
using std::min_element;
using std::minmax_element;
using std::move;
using std::none_of;
using std::nth_element;
using std::partial_sort;
using std::partial_sum;
using std::pow;
using std::rethrow_exception;
using std::reverse;
using std::round;
using std::sin;
using std::sort;
using std::sqrt;
using std::stable_sort;
using std::strerror;
using std::strtod;
using std::strtoull;
using std::tgamma;
using std::to_string;
using std::tolower;
using std::unique;
using std::upper_bound;
using std::visit;
using std::fabs;
using std::fmod;
using std::tan;
using std::atan;
using std::acos;
using std::cbrt;
using std::exit;
using std::snprintf;
using std::strlen;
}  // namespace peridot_exports
}  // namespace std

export namespace std::chrono {
inline namespace peridot_exports {
using std::chrono::duration;
using std::chrono::duration_cast;
using std::chrono::milliseconds;
using std::chrono::nanoseconds;
using std::chrono::seconds;
using std::chrono::steady_clock;
using std::chrono::operator-;
using std::chrono::operator+;
using std::chrono::operator<;
using std::chrono::operator>;
using std::chrono::operator<=;
using std::chrono::operator>=;
using std::chrono::operator==;
}  // namespace peridot_exports
}  // namespace std::chrono

export namespace std::filesystem {
inline namespace peridot_exports {
using std::filesystem::absolute;
using std::filesystem::create_directories;
using std::filesystem::exists;
using std::filesystem::file_size;
using std::filesystem::filesystem_error;
using std::filesystem::is_directory;
using std::filesystem::is_regular_file;
using std::filesystem::path;
using std::filesystem::remove;
using std::filesystem::remove_all;
using std::filesystem::rename;
using std::filesystem::temp_directory_path;
}  // namespace peridot_exports
}  // namespace std::filesystem

export namespace std::numbers {
inline namespace peridot_exports {
using std::numbers::pi;
}  // namespace peridot_exports
}  // namespace std::numbers

export namespace std::ranges {
inline namespace peridot_exports {
using std::ranges::any_of;
using std::ranges::binary_search;
using std::ranges::copy;
using std::ranges::count;
using std::ranges::sort;
using std::ranges::find;
using std::ranges::find_if;
using std::ranges::max;
using std::ranges::min;
using std::ranges::all_of;
using std::ranges::none_of;
using std::ranges::iota_view;
using std::ranges::range;
using std::ranges::begin;
using std::ranges::end;
using std::ranges::size;
}  // namespace peridot_exports
}  // namespace std::ranges

export namespace std::ranges::views {
inline namespace peridot_exports {
using std::ranges::views::filter;
using std::ranges::views::iota;
using std::ranges::views::transform;
}  // namespace peridot_exports
}  // namespace std::ranges::views

export namespace std {
namespace views = ranges::views;
}  // namespace std


// libstdc++'s vector and string iterators compare and subtract through operators in __gnu_cxx.
export namespace __gnu_cxx {
inline namespace peridot_exports {
using __gnu_cxx::operator==;
using __gnu_cxx::operator<=>;
using __gnu_cxx::operator-;
using __gnu_cxx::operator+;
}  // namespace peridot_exports
}  // namespace __gnu_cxx

// Global names the units use unqualified (the C library's, through the C++ headers).
export {
using ::size_t;
}
