// stratum/fresnel.hpp -- Fresnel reflectance of a smooth dielectric boundary, unpolarized light.
//
// Convention (one relative index, as in pbrt): light travels from medium i into medium t and
// eta = n_t / n_i. cos_i is the cosine between the incident direction and the normal on the
// incident side, in [0, 1]. A negative cos_i means the light arrives from the t side: the roles
// swap (eta -> 1/eta, cos_i -> -cos_i), so one call serves both sides of an interface.
//
// Internal diffuse reflectance (the F_dr of the dipole): fresnel_diffuse_reflectance(eta) takes
// eta = n_medium / n_outside and averages F over the hemisphere for light INSIDE the medium
// hitting the boundary; it equals fresnel_hemispherical_reflectance(1 / eta). Renderers disagree
// on this side (Mitsuba passes 1/eta); state it when you compare.
#pragma once

#include <cmath>
#include <utility>

#include "detail/config.hpp"
#include "detail/validate.hpp"
#include "quadrature.hpp"

namespace stratum {

/// Unpolarized Fresnel reflectance F(cos_i, eta), eta = n_t / n_i > 0.
///   m = eta cos_t = sqrt(cos_i^2 + k2),  k2 = eta^2 - 1     (Snell; m^2 < 0 is total internal reflection)
///   r_s = (cos_i - m) / (cos_i + m)                = -k2 / (cos_i + m)^2
///   r_p = (eta^2 cos_i - m) / (eta^2 cos_i + m)    = k2 ((eta^2 + 1) cos_i^2 - 1) / (eta^2 cos_i + m)^2
///   F = (r_s^2 + r_p^2) / 2.
/// The right-hand forms (numerators multiplied out) keep full relative accuracy as eta -> 1, where the
/// differences on the left cancel; k2 is formed as (eta - 1)(eta + 1) for the same reason, and for cos_i < 0
/// (the light on the other side: the index ratio 1 / eta) as (1 - eta)(1 + eta) / eta^2, not from the rounded
/// 1 / eta (which made F 2e-4 off at eta = 1 - 1e-12, 23% at 1 - 1e-15; found by review). eta = 1 gives exactly 0
/// at every angle; total internal reflection and grazing incidence (cos_i = 0) give 1.
template <class Real>
STRATUM_HOST_DEVICE Real fresnel_dielectric(Real cos_i, Real eta) noexcept {
    Real k2;
    if (cos_i < 0) {
        cos_i = -cos_i;
        k2 = (Real(1) - eta) * (Real(1) + eta) / (eta * eta);
        eta = Real(1) / eta;
    } else {
        k2 = (eta - Real(1)) * (eta + Real(1));
    }
    const Real m2 = cos_i * cos_i + k2;
    // TIR, and grazing incidence (exactly 1 for eta != 1: the formulas below round to 1 +- an ulp there).
    if (m2 <= 0 || cos_i == 0) return eta == Real(1) ? Real(0) : Real(1);
    const Real m = std::sqrt(m2);
    const Real e2 = eta * eta;
    const Real ds = cos_i + m, dp = e2 * cos_i + m;
    const Real rs = -k2 / (ds * ds);
    const Real rp = k2 * ((e2 + Real(1)) * cos_i * cos_i - Real(1)) / (dp * dp);
    return std::fmin(Real(1), (rs * rs + rp * rp) / Real(2));  // near grazing, rounding can exceed 1 by an ulp
}

namespace detail {

/// 2 int_0^1 F(c, eta) c dc by Gauss-Legendre on geometrically growing intervals. The integrand is
/// analytic with branch points at distance `scale` from the start of the interval (the critical
/// angle, or eta -> 1), so intervals [0, s], [s, 2s], [2s, 4s], ... keep 24 nodes per interval
/// spectrally accurate however close eta is to 1.
template <class Real, class F>
Real integrate_graded(F f, Real upper, Real scale) {
    static const Quadrature<long double> rule = gauss_legendre<long double>(24);
    long double sum = 0, a = 0, b = std::fmin(static_cast<long double>(scale), static_cast<long double>(upper));
    while (a < upper) {
        const long double half = (b - a) / 2, mid = (a + b) / 2;
        for (std::size_t i = 0; i < rule.size(); ++i) sum += rule.weights[i] * half * f(mid + half * rule.nodes[i]);
        a = b;
        b = std::fmin(2 * b, static_cast<long double>(upper));
    }
    return static_cast<Real>(sum);
}

}  // namespace detail

/// Hemispherical (cosine-weighted) average of F for light travelling from i into t, eta = n_t / n_i:
///   F_h(eta) = 2 int_0^1 F(c, eta) c dc.
/// For eta < 1 the part beyond the critical angle is 1 - eta^2 exactly; the rest is integrated in
/// t = m = sqrt(c^2 - (1 - eta^2)), which removes the square-root singularity at the critical angle.
/// Accuracy: a few ulp of double (tested against mpmath). Not a hot-path function (it loops ~10^3 times).
/// Throws std::invalid_argument unless 0 < eta < inf.
template <class Real>
Real fresnel_hemispherical_reflectance(Real eta) {
    detail::require_positive("eta", eta);
    using W = long double;
    const W e = eta;
    if (e == 1) return Real(0);
    const W e2 = e * e;
    if (e > 1) {
        // m = sqrt(c^2 + k^2), k^2 = eta^2 - 1: analytic scale k.
        const W k2 = (e - 1) * (e + 1);
        auto f = [&](W c) {
            const W m = std::sqrt(c * c + k2);
            const W rs = (c - m) / (c + m), rp = (e2 * c - m) / (e2 * c + m);
            return (rs * rs + rp * rp) * c;  // 2 * F * c
        };
        // The panels grade towards the nearer of the branch points at c = +-i k and the pole of r_p at
        // c = -m / eta^2, ~k / eta^2 from the start (for large eta far nearer: graded at k alone, F_h was 4e-7 off at
        // eta = 100 and 5e-7 at 1000; found by review).
        return detail::integrate_graded<Real>(f, Real(1), static_cast<Real>(std::fmin(std::sqrt(k2), std::sqrt(k2) / e2)));
    }
    // eta < 1: critical cosine c_c = sqrt(1 - eta^2); substitute c = sqrt(c_c^2 + t^2), c dc = t dt.
    const W cc2 = (1 - e) * (1 + e);
    auto f = [&](W t) {
        const W c = std::sqrt(cc2 + t * t);
        const W rs = (c - t) / (c + t), rp = (e2 * c - t) / (e2 * c + t);
        return (rs * rs + rp * rp) * t;
    };
    // (graded towards the nearer of sqrt(cc2) and the pole of r_p at t ~ -eta^2 sqrt(cc2), as above)
    return static_cast<Real>(cc2 + static_cast<W>(detail::integrate_graded<Real>(
                                       f, static_cast<Real>(e), static_cast<Real>(std::fmin(std::sqrt(cc2), e2 * std::sqrt(cc2))))));
}

/// Internal diffuse Fresnel reflectance F_dr of a medium of relative index eta = n_medium / n_outside:
/// the hemispherical average of F for light inside the medium reaching its boundary (the F_dr of
/// Jensen et al. 2001's A = (1 + F_dr) / (1 - F_dr)). Exact (numerical integration, see above).
template <class Real>
Real fresnel_diffuse_reflectance(Real eta) {
    detail::require_positive("eta", eta);
    return fresnel_hemispherical_reflectance(Real(1) / eta);
}

/// The Egan-Hilgeman fit of F_dr used by Jensen et al. 2001, same eta as fresnel_diffuse_reflectance:
///   F_dr ~ -1.440 / eta^2 + 0.710 / eta + 0.668 + 0.0636 eta.
/// Measured absolute error against the exact integral (tests/test_fresnel.cpp): <= 0.00161 for eta in
/// [1, 2] (largest at eta = 1, where the exact value is 0), <= 0.0159 for eta in [1, 3] (largest at 3).
/// The fit is meant for eta >= 1; below 1 it is wrong (negative): use the exact function there.
template <class Real>
Real fresnel_diffuse_reflectance_fit(Real eta) {
    detail::require_positive("eta", eta);
    return Real(-1.440) / (eta * eta) + Real(0.710) / eta + Real(0.668) + Real(0.0636) * eta;
}

}  // namespace stratum
