// stratum/lambert_w.hpp -- the lower real branch W_{-1} of the Lambert W function.
//
// W_{-1}(x) is the solution w <= -1 of  w e^w = x  for x in [-1/e, 0); it falls from -1 at the
// branch point x = -1/e to -inf as x -> 0-. The dipole's radial sampler inverts the CDF
// 1 - e^{-u}(1 + u) with it (dipole.hpp).
//
// Method.
//  * Near the branch point the function is a series in p = sqrt(2 (e x + 1)):
//      W_{-1} = -1 - p - p^2/3 - 11/72 p^3 - 43/540 p^4 - 769/17280 p^5 - ...
//    (Corless et al. 1996, eq. 4.22; the coefficients come from their recurrence (4.23-4.24) with p -> -p,
//    so every term is negative and the sum has no cancellation). Radius of convergence p = sqrt(2).
//  * Elsewhere the asymptotic expansion in L1 = ln(-x), L2 = ln(-L1) starts the iteration:
//      W ~ L1 - L2 + L2/L1 + L2 (L2 - 2) / (2 L1^2).
//  * Then Fritsch's iteration (Fritsch, Shafer & Crowley 1973), w <- w (1 + eps) with
//      z = ln(x / w) - w,  t = 2 (1 + w) (1 + w + 2z/3),  eps = z (t - z) / ((1 + w) (t - 2z)),
//    which gains about four times the digits per step.
//  * The branch point is ill-conditioned: dW/dx = W / (x (1 + W)) is infinite there, so the rounding of
//    e x + 1 ruins the result unless that offset q = e x + 1 is formed accurately. It is: 1/e is carried
//    as a double-double, x + hi(1/e) is exact (Sterbenz) and the low part is added afterwards. With q in
//    hand the iteration is rewritten so that nothing cancels: ln(-x) = log1p(-q) - 1 and
//    ln(-w) = log1p(-(1 + w)), so z = log1p(-q) - log1p(-v) - v with v = 1 + w (exact near w = -1).
//    Callers that know q better than x (e.g. q = xi in the sampler) use detail::lambert_wm1_plus_one, which
//    returns 1 + W with full relative accuracy (W itself rounds to -1 there).
//
// Accuracy (tests/test_lambert_w.cpp, against mpmath at the exact floating-point argument; asserted / measured):
// double 3 / 1.5 ulp over the whole domain, including the 40 doubles next to -1/e and subnormal x; float
// 3 / 2.39 ulp (every float of [-1/e, -1e-3] against long double); long double 4 / 2.1 eps. Cost: 1-2 Fritsch steps (one log each) after the start (BM_dipole_sample_radius).
#pragma once

#include <cmath>
#include <limits>

#include "detail/config.hpp"

namespace stratum {
namespace detail {

/// 1/e = inv_e_0 + inv_e_1 + inv_e_2 (each a double; 159 bits); inv_e_0 > 1/e.
inline constexpr double inv_e_0 = 0x1.78b56362cef38p-2;
inline constexpr double inv_e_1 = -0x1.ca8a4270fadf5p-57;
inline constexpr double inv_e_2 = -0x1.837912b3fd2aap-111;

/// 1/e split into Real hi + lo, hi = 1/e rounded to Real, lo the rest (to Real precision).
template <class Real>
struct InvE {
    static constexpr long double sum = static_cast<long double>(inv_e_0) + static_cast<long double>(inv_e_1) +
                                       static_cast<long double>(inv_e_2);
    static constexpr Real hi = static_cast<Real>(sum);
    static constexpr Real lo = static_cast<Real>(
        ((static_cast<long double>(inv_e_0) - static_cast<long double>(hi)) + static_cast<long double>(inv_e_1)) +
        static_cast<long double>(inv_e_2));
};

template <class Real>
inline constexpr Real euler_e = static_cast<Real>(2.718281828459045235360287471352662498L);

/// 1 + W_{-1} near the branch point: -sum_k |mu_k| p^k, k = 1..13 (Horner), full relative accuracy.
template <class Real>
STRATUM_HOST_DEVICE Real lambert_wm1_branch_series_plus_one(Real p) noexcept {
    // |mu_k| of the branch-point series (tests/data/gen_lambert_w.py prints them to 25 digits).
    constexpr Real c[] = {Real(1),
                          Real(0.3333333333333333333333333L),
                          Real(0.1527777777777777777777778L),
                          Real(0.07962962962962962962962963L),
                          Real(0.04450231481481481481481481L),
                          Real(0.02598471487360376249265138L),
                          Real(0.01563563253233392122281011L),
                          Real(0.009616892024299431706839114L),
                          Real(0.006014543252956117860953252L),
                          Real(0.003811298034891999226704302L),
                          Real(0.002440877991143982665896859L),
                          Real(0.00157693034468678425392341L),
                          Real(0.001026263320507607154437548L)};
    constexpr int n = static_cast<int>(sizeof c / sizeof c[0]);
    Real s = c[n - 1];
    for (int k = n - 2; k >= 0; --k) s = c[k] + p * s;
    return -p * s;
}


/// 1 + W_{-1}(x), where the caller also supplies the branch offset q = e x + 1 in [0, 1], accurate in a
/// relative sense (x itself need only be accurate where q >= 1/2; x = (q - 1) / e must hold to rounding).
/// Near the branch point the result keeps full relative accuracy although W_{-1} itself is ~ -1: the
/// iteration runs on v = 1 + w. (The radial sampler needs exactly this: u = -(1 + W_{-1}).)
template <class Real>
STRATUM_HOST_DEVICE Real lambert_wm1_plus_one(Real x, Real q) noexcept {
    constexpr Real eps = std::numeric_limits<Real>::epsilon();
    if (!(q > 0)) return Real(0);                                           // the branch point
    if (!(x < 0)) return -std::numeric_limits<Real>::infinity();            // x -> 0-
    // Fritsch's correction shrinks like e -> O(e^4): once |e| < eps^{1/4} / 8 the step just taken was the last
    // one needed.
    const Real tol = std::sqrt(std::sqrt(eps)) / 8;
    if (q < Real(0.5)) {
        // v = 1 + w from the branch series, then the iteration written in q and v (nothing cancels).
        const Real p = std::sqrt(2 * q);
        Real v = lambert_wm1_branch_series_plus_one(p);
        // Truncation error < |mu_14| p^14 (|mu_14| = 6.7e-4, coefficients fall like 2^{-k/2}): when that is
        // below eps/4 relative to v ~ -p the series is the answer (p < 0.07 in double).
        const Real p2 = p * p, p4 = p2 * p2, p13 = p4 * p4 * p4 * p;
        if (Real(1e-3) * p13 < eps / 4) return v;
        const Real log1p_mq = std::log1p(-q);
        for (int iter = 0; iter < 6; ++iter) {
            const Real z = log1p_mq - std::log1p(-v) - v;     // ln(x / w) - w
            const Real t = 2 * v * (v + Real(2) / 3 * z);
            const Real e = z / v * (t - z) / (t - 2 * z);
            v += (v - 1) * e;                                 // w <- w (1 + e)
            if (std::fabs(e) < tol) break;
        }
        return v;
    }
    const Real log_mx = std::log(-x), l2 = std::log(-log_mx);
    Real w = log_mx - l2 + l2 / log_mx + l2 * (l2 - 2) / (2 * log_mx * log_mx);
    for (int iter = 0; iter < 6; ++iter) {
        const Real v = 1 + w;
        // ln(x / w) - w, taken apart so that a subnormal x / w cannot lose digits.
        const Real z = (log_mx - std::log(-w)) - w;
        const Real t = 2 * v * (v + Real(2) / 3 * z);
        const Real e = z / v * (t - z) / (t - 2 * z);
        w += w * e;
        if (std::fabs(e) < tol) break;
    }
    return 1 + w;
}

}  // namespace detail

/// Lower branch of the Lambert W function: the w <= -1 with w e^w = x, for x in [-1/e, 0).
/// W_{-1}(-1/e) = -1 (also returned for the Real nearest -1/e, which lies just below -1/e);
/// W_{-1}(0-) = -inf, returned for x = 0. Outside [-1/e, 0] (or NaN) the result is NaN.
/// Accuracy: a few ulp of Real everywhere, including next to the branch point (see the header comment).
template <class Real>
STRATUM_HOST_DEVICE Real lambert_wm1(Real x) noexcept {
    using IE = detail::InvE<Real>;
    if (!(x >= -IE::hi && x <= 0)) return std::numeric_limits<Real>::quiet_NaN();
    // q = e (x + 1/e): exact sum x + hi for x in [-hi, -hi/2], then the low part; one rounding in the product.
    const Real q = x < -IE::hi / 2 ? detail::euler_e<Real> * ((x + IE::hi) + IE::lo) : 1 + detail::euler_e<Real> * x;
    return detail::lambert_wm1_plus_one(x, q) - 1;
}

}  // namespace stratum
