// stratum/detail/elliptic.hpp -- complete elliptic integrals through Carlson's symmetric forms.
//
// Used by the closed-form azimuthal Fourier coefficients of the Henyey-Greenstein phase function.
// Not part of the public API.
//
// R_F(x, y, z) = (1/2) int_0^inf dt / sqrt((t + x)(t + y)(t + z)),
// R_D(x, y, z) = (3/2) int_0^inf dt / ((t + z) sqrt((t + x)(t + y)(t + z))),
// computed by Carlson's duplication theorem (B. C. Carlson, Numer. Algorithms 10 (1995) 13-26):
// each step replaces (x, y, z) by ((x + lambda)/4, ...), lambda = sqrt(xy) + sqrt(yz) + sqrt(zx), which
// shrinks the spread of the arguments fourfold; once it is below ~eps^(1/6) of the mean, a fifth-order
// Taylor series in the normalized deviations finishes (DLMF 19.36.1 and 19.36.2).
// Complete integrals in terms of the complementary parameter c = k'^2 = 1 - k^2 (DLMF 19.25.1):
//   K(k) = R_F(0, c, 1),   E(k) = (c / 3) (R_D(0, c, 1) + R_D(0, 1, c)),
// both forms free of cancellation as k -> 1 (c -> 0), where the Fourier coefficients need them.
#pragma once

#include <cmath>
#include <limits>

namespace stratum::detail {

/// Largest relative spread of the arguments at which the fifth-order series is accurate to ~eps.
template <class Real>
Real carlson_tolerance() noexcept {
    // Truncation error ~ spread^6 / 20 (DLMF 19.36): spread = (eps)^(1/6) / 2 leaves ~eps/1000.
    return std::pow(std::numeric_limits<Real>::epsilon(), Real(1) / Real(6)) / Real(2);
}

/// Carlson's R_F(x, y, z) for x, y, z >= 0, at most one of them zero.
template <class Real>
Real carlson_rf(Real x, Real y, Real z) noexcept {
    const Real tol = carlson_tolerance<Real>();
    Real a = (x + y + z) / Real(3);
    for (int i = 0; i < 200; ++i) {
        const Real spread = std::fmax(std::fabs(a - x), std::fmax(std::fabs(a - y), std::fabs(a - z)));
        if (spread <= tol * a) break;
        const Real sx = std::sqrt(x), sy = std::sqrt(y), sz = std::sqrt(z);
        const Real lambda = sx * sy + sy * sz + sz * sx;
        x = (x + lambda) / Real(4);
        y = (y + lambda) / Real(4);
        z = (z + lambda) / Real(4);
        a = (a + lambda) / Real(4);
    }
    const Real X = (a - x) / a, Y = (a - y) / a, Z = -(X + Y);
    const Real e2 = X * Y - Z * Z, e3 = X * Y * Z;
    return (Real(1) - e2 / Real(10) + e3 / Real(14) + e2 * e2 / Real(24) - Real(3) * e2 * e3 / Real(44)) / std::sqrt(a);
}

/// Carlson's R_D(x, y, z) for x, y >= 0 (at most one zero), z > 0.
template <class Real>
Real carlson_rd(Real x, Real y, Real z) noexcept {
    const Real tol = carlson_tolerance<Real>();
    Real a = (x + y + Real(3) * z) / Real(5);
    Real sum = 0, scale = 1;
    for (int i = 0; i < 200; ++i) {
        const Real spread = std::fmax(std::fabs(a - x), std::fmax(std::fabs(a - y), std::fabs(a - z)));
        if (spread <= tol * a) break;
        const Real sx = std::sqrt(x), sy = std::sqrt(y), sz = std::sqrt(z);
        const Real lambda = sx * sy + sy * sz + sz * sx;
        sum += scale / (sz * (z + lambda));
        scale /= Real(4);
        x = (x + lambda) / Real(4);
        y = (y + lambda) / Real(4);
        z = (z + lambda) / Real(4);
        a = (a + lambda) / Real(4);
    }
    const Real X = (a - x) / a, Y = (a - y) / a, Z = -(X + Y) / Real(3);
    const Real xy = X * Y, z2 = Z * Z;
    const Real e2 = xy - Real(6) * z2, e3 = (Real(3) * xy - Real(8) * z2) * Z;
    const Real e4 = Real(3) * (xy - z2) * z2, e5 = xy * z2 * Z;
    const Real series = Real(1) - Real(3) * e2 / Real(14) + e3 / Real(6) + Real(9) * e2 * e2 / Real(88) -
                        Real(3) * e4 / Real(22) - Real(9) * e2 * e3 / Real(52) + Real(3) * e5 / Real(26);
    return Real(3) * sum + scale * series / (a * std::sqrt(a));
}

/// Complete elliptic integrals K, E and their difference K - E of modulus k.
template <class Real>
struct CompleteElliptic {
    Real K, E, K_minus_E;
};

/// From the parameter m = k^2 and its complement c = 1 - m (both passed, so that whichever is small
/// keeps its relative accuracy): K = R_F(0, c, 1), E = (c/3)(R_D(0, c, 1) + R_D(0, 1, c)),
/// K - E = (m/3) R_D(0, c, 1) (DLMF 19.25.1; all three free of cancellation). 0 <= m < 1.
template <class Real>
CompleteElliptic<Real> complete_elliptic(Real m, Real c) noexcept {
    const Real K = carlson_rf(Real(0), c, Real(1));
    const Real rd = carlson_rd(Real(0), c, Real(1));
    const Real E = c / Real(3) * (rd + carlson_rd(Real(0), Real(1), c));
    return {K, E, m / Real(3) * rd};
}

}  // namespace stratum::detail
