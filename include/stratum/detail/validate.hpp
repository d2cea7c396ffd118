// stratum/detail/validate.hpp -- parameter validation shared by every module.
//
// Validation happens once, where a parameter object is constructed; evaluation functions
// never check. A rejected value raises std::invalid_argument whose message names the
// parameter, its value and the allowed range, e.g.
//   "stratum: g = 1 is outside the allowed range (-1, 1)".
// Built without exceptions (-fno-exceptions), the message goes instead to the handler set with
// stratum::set_invalid_parameter_handler, and then the program aborts: construction never goes on
// with a bad value. The detail:: functions are not part of the public API.
#pragma once

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

#include "config.hpp"

namespace stratum {

/// Receives the message of a rejected parameter in builds without exceptions (e.g. to log it) before
/// the program aborts. Not used when exceptions are enabled.
using InvalidParameterHandler = void (*)(const char* message);

namespace detail {
inline InvalidParameterHandler& invalid_parameter_handler_slot() noexcept {
    static InvalidParameterHandler handler = nullptr;
    return handler;
}
}  // namespace detail

/// Sets the handler for builds without exceptions; returns the previous one (nullptr: print to stderr).
inline InvalidParameterHandler set_invalid_parameter_handler(InvalidParameterHandler handler) noexcept {
    InvalidParameterHandler previous = detail::invalid_parameter_handler_slot();
    detail::invalid_parameter_handler_slot() = handler;
    return previous;
}

}  // namespace stratum

namespace stratum::detail {

/// Throws std::invalid_argument(message), or without exceptions reports it and aborts.
[[noreturn]] inline void fail_invalid_argument(const std::string& message) {
#if STRATUM_EXCEPTIONS
    throw std::invalid_argument(message);
#else
    if (InvalidParameterHandler handler = invalid_parameter_handler_slot()) {
        handler(message.c_str());
    } else {
        std::fprintf(stderr, "%s\n", message.c_str());
    }
    std::abort();
#endif
}

/// As fail_invalid_argument, for a numerical method that cannot proceed (std::domain_error).
[[noreturn]] inline void fail_domain_error(const std::string& message) {
#if STRATUM_EXCEPTIONS
    throw std::domain_error(message);
#else
    fail_invalid_argument(message);
#endif
}

/// As fail_invalid_argument, for input/output that cannot proceed (std::runtime_error: a file unreadable, truncated or
/// not of the expected format).
[[noreturn]] inline void fail_runtime_error(const std::string& message) {
#if STRATUM_EXCEPTIONS
    throw std::runtime_error(message);
#else
    fail_invalid_argument(message);
#endif
}

/// Formats a value with enough digits to round-trip (so 1 - 1e-17 does not print as "1").
template <class Real>
std::string format_value(Real value) {
    std::ostringstream out;
    out.precision(std::numeric_limits<Real>::max_digits10);
    out << value;
    return out.str();
}

/// Fails with "stratum: <name> = <value> is outside the allowed range <range>" (fail_invalid_argument).
template <class Real>
[[noreturn]] void throw_out_of_range(const char* name, Real value, const std::string& range) {
    fail_invalid_argument(std::string("stratum: ") + name + " = " + format_value(value) +
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

/// Requires a refractive index in [1e-4, 1e4]: every physical index lies far inside, and the Fresnel and
/// BTDF formulas, which use up to the fourth power of an index ratio, stay finite in float and double.
template <class Real>
Real require_refractive_index(const char* name, Real value) {
    if (!(value >= Real(1e-4) && value <= Real(1e4))) throw_out_of_range(name, value, "[0.0001, 10000]");
    return value;
}

/// Requires an integer count >= lo.
inline int require_count(const char* name, int value, int lo) {
    if (value < lo) throw_out_of_range(name, value, "[" + std::to_string(lo) + ", inf)");
    return value;
}

}  // namespace stratum::detail
