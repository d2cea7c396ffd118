// stratum/detail/validate.hpp -- parameter validation shared by every module.
//
// Validation happens once, where a parameter object is constructed; evaluation functions
// never check. A rejected value raises std::invalid_argument whose message names the
// parameter, its value and the allowed range, e.g.
//   "stratum: g = 1 is outside the allowed range (-1, 1)".
// Not part of the public API.
#pragma once

#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

namespace stratum::detail {

/// Formats a value with enough digits to round-trip (so 1 - 1e-17 does not print as "1").
template <class Real>
std::string format_value(Real value) {
    std::ostringstream out;
    out.precision(std::numeric_limits<Real>::max_digits10);
    out << value;
    return out.str();
}

/// Throws std::invalid_argument "stratum: <name> = <value> is outside the allowed range <range>".
template <class Real>
[[noreturn]] void throw_out_of_range(const char* name, Real value, const std::string& range) {
    throw std::invalid_argument(std::string("stratum: ") + name + " = " + format_value(value) +
                                " is outside the allowed range " + range);
}

/// Requires lo < value < hi (open interval). NaN always fails.
template <class Real>
Real require_open(const char* name, Real value, Real lo, Real hi) {
    if (!(value > lo && value < hi))
        throw_out_of_range(name, value, "(" + format_value(lo) + ", " + format_value(hi) + ")");
    return value;
}

/// Requires lo <= value <= hi (closed interval). NaN always fails.
template <class Real>
Real require_closed(const char* name, Real value, Real lo, Real hi) {
    if (!(value >= lo && value <= hi))
        throw_out_of_range(name, value, "[" + format_value(lo) + ", " + format_value(hi) + "]");
    return value;
}

/// Requires a finite value > 0.
template <class Real>
Real require_positive(const char* name, Real value) {
    if (!(value > 0 && std::isfinite(value))) throw_out_of_range(name, value, "(0, inf)");
    return value;
}

/// Requires a finite value >= 0.
template <class Real>
Real require_nonnegative(const char* name, Real value) {
    if (!(value >= 0 && std::isfinite(value))) throw_out_of_range(name, value, "[0, inf)");
    return value;
}

/// Requires an integer count >= lo.
inline int require_count(const char* name, int value, int lo) {
    if (value < lo) throw_out_of_range(name, value, "[" + std::to_string(lo) + ", inf)");
    return value;
}

}  // namespace stratum::detail
