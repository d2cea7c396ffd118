// tests/test_util.hpp -- helpers shared by the doctest suites (not installed).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <type_traits>
#include <vector>

#include <stratum/vec3.hpp>

namespace stratum_test {

inline constexpr double pi = 3.141592653589793238462643383279502884;

/// A double uniform on [0, 1) from the top 53 bits (own mapping: independent of the library and of the
/// standard library's distributions, whose output differs between implementations).
inline double uniform(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1p-53; }

/// A direction uniform on the sphere (own mapping, independent of the library).
inline stratum::Vec3<double> random_direction(std::mt19937_64& rng) {
    const double z = 2 * uniform(rng) - 1, phi = 2 * pi * uniform(rng);
    const double s = std::sqrt(std::fmax(0.0, 1 - z * z));
    return {s * std::cos(phi), s * std::sin(phi), z};
}

/// The unit vector of cosine mu (its sign: the hemisphere) at azimuth phi (own formula, as above).
inline stratum::Vec3<double> direction_at(double mu, double phi) {
    const double s = std::sqrt((1 - mu) * (1 + mu));
    return {s * std::cos(phi), s * std::sin(phi), mu};
}

/// Unpolarized Fresnel reflectance of a dielectric for cos(incidence) c and relative index n (Born & Wolf),
/// written out here so that tests do not share code with fresnel.hpp; g - c = (n - 1)(n + 1) / (g + c) keeps
/// the relative accuracy for n near 1. Total internal reflection (n^2 - 1 + c^2 < 0) gives 1. In double, or in long
/// double for references of double results.
template <class T>
T fresnel_closed_form(T c, T n) {
    const T g2 = (n - 1) * (n + 1) + c * c;
    if (g2 <= 0) return T(1);
    const T g = std::sqrt(g2);
    const T a = (n - 1) * (n + 1) / ((g + c) * (g + c)), b = (c * (g + c) - 1) / (c * (g - c) + 1);
    return a * a * (1 + b * b) / 2;
}

/// Distance in units in the last place between two finite values of the same type: the number of
/// representable values strictly between them plus one (0 when equal; +0 and -0 are equal).
/// Works for float and double by mapping the bit pattern onto a monotone integer line.
template <class Real>
std::int64_t ulp_distance(Real a, Real b) {
    static_assert(std::is_same_v<Real, float> || std::is_same_v<Real, double>,
                  "ulp_distance supports float and double");
    if (std::isnan(a) || std::isnan(b)) return std::numeric_limits<std::int64_t>::max();
    using Bits = std::conditional_t<std::is_same_v<Real, float>, std::int32_t, std::int64_t>;
    auto ordered = [](Real x) {
        Bits bits;
        std::memcpy(&bits, &x, sizeof bits);
        // Negative values: flip to a monotone ordering below zero.
        return bits < 0 ? static_cast<std::int64_t>(std::numeric_limits<Bits>::min()) - bits
                        : static_cast<std::int64_t>(bits);
    };
    const std::int64_t d = ordered(a) - ordered(b);
    return d < 0 ? -d : d;
}

/// |a - b| <= tol * max(|a|, |b|), with tol relative. Use for values that are never near zero.
template <class Real>
bool close_rel(Real a, Real b, Real tol) {
    return std::fabs(a - b) <= tol * std::fmax(std::fabs(a), std::fabs(b));
}

/// Pearson's chi-square of observed counts against expected counts, with every bin expecting fewer than
/// `min_expected` pooled into one extra bin (kept only if the pool itself expects at least that many).
struct ChiSquare {
    double value = 0;
    int bins = 0;
};
inline ChiSquare pooled_chi_square(const std::vector<double>& expected, const std::vector<double>& observed,
                                   double min_expected = 20) {
    ChiSquare c;
    double pool_e = 0, pool_o = 0;
    for (std::size_t i = 0; i < expected.size(); ++i) {
        if (expected[i] < min_expected) {
            pool_e += expected[i];
            pool_o += observed[i];
            continue;
        }
        c.value += (observed[i] - expected[i]) * (observed[i] - expected[i]) / expected[i];
        ++c.bins;
    }
    if (pool_e >= min_expected) {
        c.value += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
        ++c.bins;
    }
    return c;
}

}  // namespace stratum_test
