// stratum/detail/math.hpp -- math helpers shared by the modules (not part of the public API): constants,
// the widened working type, a non-deduced template context, polynomial evaluation, log-gamma and local
// Lagrange interpolation weights.
//
// Everything here is noexcept, allocation-free and thread-safe: no global state is read or written. (This is
// why the library has its own log-gamma: glibc's std::lgamma writes the global `signgam` on every call, a data
// race when two threads evaluate a BTDF at once.) Templates on the working type W (double or long double;
// float works but is never needed: callers compute in detail::wide_t). STRATUM_HOST_DEVICE (config.hpp) so that
// the pointwise evaluation functions built on them can run on a GPU.
#pragma once

#include <cmath>
#include <limits>
#include <type_traits>

#include "config.hpp"

namespace stratum::detail {

/// Constants, each a correctly rounded long double literal converted once to W.
template <class W>
inline constexpr W pi_v = W(3.141592653589793238462643383279502884L);
template <class W>
inline constexpr W two_pi_v = W(6.283185307179586476925286766559005768L);
template <class W>
inline constexpr W inv_pi_v = W(0.318309886183790671537767526745028724L);
template <class W>
inline constexpr W inv_four_pi_v = W(0.0795774715459476678844418816862571810L);
template <class W>
inline constexpr W sqrt_pi_v = W(1.772453850905516027298167483341145183L);

/// The type in which internal iterations run: at least double (float loses the tails of erfc, and the
/// products of tiny and huge factors in the microfacet terms overflow).
template <class Real>
using wide_t = std::conditional_t<(sizeof(Real) < sizeof(double)), double, Real>;

/// w rounded to Real, with values beyond Real's range saturated at its largest finite value (NaN stays
/// NaN). For densities that diverge where a cosine vanishes (a microfacet BRDF at a grazing direction):
/// the exact value may exceed Real's range there although its product with that cosine does not.
template <class Real, class W>
STRATUM_HOST_DEVICE Real saturate_to(W w) noexcept {
    constexpr Real largest = std::numeric_limits<Real>::max();
    return w > static_cast<W>(largest) ? largest : static_cast<Real>(w);
}

/// A sampler's uniform variate clamped into [0, 1 - eps/2], NaN and negatives to 0: an argument from outside [0, 1)
/// gives the sample at the nearest end, never an index out of range, a NaN or an infinite distance.
template <class Real>
STRATUM_HOST_DEVICE Real clamp_uniform(Real u) noexcept {
    constexpr Real below_one = 1 - std::numeric_limits<Real>::epsilon() / 2;
    return u > 0 ? (u < below_one ? u : below_one) : Real(0);
}

/// T in a context where it is not deduced, so that arguments convert to it (a RoughDielectric to a
/// Boundary in solve_layer) instead of taking part in template argument deduction.
template <class T>
struct non_deduced {
    using type = T;
};
template <class T>
using non_deduced_t = typename non_deduced<T>::type;

/// p[0] + p[1] t + ... + p[n - 1] t^{n-1}, n a multiple of 4, as four interleaved Horner chains in t^4
/// (p0(t^4) + t p1(t^4) + t^2 (p2(t^4) + t p3(t^4))): a quarter of Horner's dependency chain, for |t| << 1.
template <class W, int n>
STRATUM_HOST_DEVICE W polynomial4(const W* p, W t) noexcept {
    static_assert(n % 4 == 0, "pad the coefficients to a multiple of 4");
    const W t2 = t * t, t4 = t2 * t2;
    W r0 = p[n - 4], r1 = p[n - 3], r2 = p[n - 2], r3 = p[n - 1];
    for (int j = n - 8; j >= 0; j -= 4) {
        r0 = r0 * t4 + p[j];
        r1 = r1 * t4 + p[j + 1];
        r2 = r2 * t4 + p[j + 2];
        r3 = r3 * t4 + p[j + 3];
    }
    return r0 + t * r1 + t2 * (r2 + t * r3);
}

/// Where Stirling's series below takes over: x >= 10 for double (first omitted term 1/(156 x^13) <= 6.4e-16,
/// 0.36 ulp of lnGamma(10) = 12.8), x >= 20 for wider types (<= 7.8e-20, 0.01 ulp of lnGamma(20) in long double).
template <class W>
STRATUM_HOST_DEVICE constexpr W stirling_min() noexcept {
    return std::numeric_limits<W>::digits > 53 ? W(20) : W(10);
}

/// The remainder of Stirling's series, lnGamma(x) - [(x - 1/2) ln x - x + ln(2 pi) / 2], for x >= stirling_min:
/// sum_{k=1..6} B_2k / (2k (2k - 1) x^{2k-1}) = 1/(12 x) - 1/(360 x^3) + 1/(1260 x^5) - 1/(1680 x^7)
/// + 1/(1188 x^9) - 691/(360360 x^11).
template <class W>
STRATUM_HOST_DEVICE W stirling_series(W x) noexcept {
    const W r = 1 / x, r2 = r * r;
    return r * (W(1) / 12 -
                r2 * (W(1) / 360 -
                      r2 * (W(1) / 1260 - r2 * (W(1) / 1680 - r2 * (W(1) / 1188 - r2 * (W(691) / 360360))))));
}

/// lnGamma(x) for x >= 1 (the only range the library needs: 1 + Lambda, 2 + Lambda + Lambda'); thread-safe
/// replacement of std::lgamma. Methods:
/// - 1 <= x <= 2.5: Taylor series of lnGamma(2 + t) about t = 0, with |t| <= 1/2,
///     lnGamma(2 + t) = (1 - gamma) t + sum_{k >= 2} (-1)^k (zeta(k) - 1) t^k / k,
///   (coefficients from mpmath; the terms fall like 4^{-k}: 32 coefficients leave < 1e-20 for double, 40 for
///   wider types < 3e-26), and lnGamma(1 + t) = lnGamma(2 + t) - log1p(t) below 1.5. t = x - 1 or x - 2 is
///   exact, so the result keeps its relative accuracy at the zeros x = 1 and x = 2.
/// - 2.5 < x < stirling_min: down to [1.5, 2.5] by lnGamma(x) = ln((x - 1) ... (x - n)) + lnGamma(x - n)
///   (x - j exact; at most 18 positive factors).
/// - x >= stirling_min: (x - 1/2) ln x - x + ln(2 pi) / 2 + stirling_series(x).
/// Accuracy (tests/test_math.cpp, against glibc's lgamma on 20 000 log-spaced points in [1, 1e6] and the ends
/// of the ranges): at most 2 ulp where |lnGamma| >= 0.5, at most 1.1e-16 absolute (5 ulp) near the zeros;
/// against mpmath (201 points): 3 eps relative, 4.4e-17 absolute near the zeros; long double against lgammal:
/// 2.2e-19 relative. +inf for x = +inf; x < 1 is
/// outside the contract (NaN is returned for NaN).
template <class W>
STRATUM_HOST_DEVICE W log_gamma(W x) noexcept {
    // Taylor coefficients of lnGamma(2 + t) about t = 0, from mpmath: c_1 = 1 - gamma, c_k = (-1)^k (zeta(k) - 1) / k.
    // static constexpr: constant-initialized (no guard), not copied to the stack on every call.
    constexpr int terms = std::numeric_limits<W>::digits > 53 ? 40 : 32;  // a multiple of 4 (polynomial4)
    static constexpr W c[40] = {
        W(0.0L), W(4.227843350984671393934879e-1L), W(3.224670334241132182362076e-1L),
        W(-6.735230105319809513324605e-2L), W(2.058080842778454787900092e-2L), W(-7.385551028673985266273097e-3L),
        W(2.890510330741523285752988e-3L), W(-1.192753911703260977113936e-3L), W(5.096695247430424223356548e-4L),
        W(-2.231547584535793797614188e-4L), W(9.945751278180853371459589e-5L), W(-4.49262367381331417002075e-5L),
        W(2.05072127756706915531665e-5L), W(-9.439488275268395903987425e-6L), W(4.374866789907487804181793e-6L),
        W(-2.039215753801366236781901e-6L), W(9.55141213040741983285718e-7L), W(-4.49246919876456604329429e-7L),
        W(2.120718480555466586923136e-7L), W(-1.004322482396809960872083e-7L), W(4.769810169363980565760193e-8L),
        W(-2.271109460894316491031998e-8L), W(1.083865921489695409107492e-8L), W(-5.183475041970046655121249e-9L),
        W(2.483674543802478317185009e-9L), W(-1.192140140586091207442548e-9L), W(5.731367241678862013330195e-10L),
        W(-2.75952288512423314517815e-10L), W(1.330476437424448948149716e-10L), W(-6.422964563838100022082448e-11L),
        W(3.104424774732227276239216e-11L), W(-1.502138408075414217093301e-11L), W(7.27597448023907966250455e-12L),
        W(-3.527742476575915083615072e-12L), W(1.711991790559617908601084e-12L), W(-8.315385841420284819798358e-13L),
        W(4.042200525289440065536009e-13L), W(-1.966475631096616490411046e-13L), W(9.573630387838555763782201e-14L),
        W(-4.664076026428374224576493e-14L)};
    if (x >= stirling_min<W>()) {
        if (!(x < std::numeric_limits<W>::infinity())) return x;
        return (x - W(0.5)) * std::log(x) - x + W(0.9189385332046727417803297364056176398614L) + stirling_series(x);
    }
    if (x < W(1.5)) {
        const W t = x - 1;
        return polynomial4<W, terms>(c, t) - std::log1p(t);
    }
    W p = 1;
    while (x > W(2.5)) {
        x -= 1;
        p *= x;
    }
    return std::log(p) + polynomial4<W, terms>(c, x - 2);
}

/// ln Gamma(z) - ln Gamma(z + b) for z >= 1, b >= 0, without the cancellation of two log-gamma calls:
/// z is shifted to >= stirling_min by the recurrence, then Stirling's series (stirling_series) with
/// (z - 1/2) ln z - (y - 1/2) ln y = -(y - 1/2) log1p(b / z) - b ln z, y = z + b.
template <class W>
STRATUM_HOST_DEVICE W log_gamma_ratio(W z, W b) noexcept {
    W p = 1, q = 1;
    while (z < stirling_min<W>()) {
        p *= z;
        q *= z + b;
        z += 1;
    }
    const W y = z + b;
    return -(y - W(0.5)) * std::log1p(b / z) - b * std::log(z) + b + stirling_series(z) - stirling_series(y) +
           std::log(q / p);
}

/// ln B(1 + a, 1 + b) = lnGamma(1 + a) + lnGamma(1 + b) - lnGamma(2 + a + b) for finite a, b >= 0: the larger
/// argument goes into log_gamma_ratio, so no two large log-gammas cancel. Relative error of B against mpmath on
/// the grid of tests/test_math.cpp: <= 1.1e-14 for a, b <= 20, 6.5e-14 for a, b <= 1e3, 1.4e-13 up to 1e6
/// (the three-lgamma form it replaces: 9.4e-15, 9.0e-13 and 2.0e-9).
template <class W>
STRATUM_HOST_DEVICE W log_beta1(W a, W b) noexcept {
    const W big = a < b ? b : a, small = a < b ? a : b;
    return log_gamma(1 + small) + log_gamma_ratio(1 + big, 1 + small);
}

/// The stencil lagrange_weights chose: nodes[first .. first + points - 1].
struct LagrangeWindow {
    int first;
    int points;
};

/// Local Lagrange interpolation at x: the weights of the p-point interpolating polynomial on the p consecutive
/// nodes nearest to x among nodes[lowest .. count - 1] (ascending; p is reduced to count - lowest where that is
/// fewer), w[a] = prod_{b != a} (x - x_b) / (x_a - x_b) for node first + a, a < p. The weights sum to 1 (up to
/// rounding) and reproduce polynomials of degree < p. The stencil has p / 2 nodes above x where it can and is
/// clamped to the ends, where it extrapolates (so weights may be negative or exceed 1). `nodes` is anything
/// indexable by std::size_t: a pointer to the ordinates (interface_operators.hpp, layer.hpp) or a grid computing
/// its nodes (the equispaced tables of layer.hpp). Requires lowest < count.
template <class Nodes, class W>
STRATUM_HOST_DEVICE LagrangeWindow lagrange_weights(const Nodes& nodes, int count, W x, int p, W* w,
                                                    int lowest = 0) noexcept {
    if (p > count - lowest) p = count - lowest;
    // The first node above x, by bisection (a NaN x compares false and gives `lowest`, as a linear scan would).
    int above = lowest, end = count;
    while (above < end) {
        const int mid = above + (end - above) / 2;
        if (nodes[static_cast<std::size_t>(mid)] <= x) above = mid + 1;
        else end = mid;
    }
    int first = above - p / 2;
    if (first > count - p) first = count - p;
    if (first < lowest) first = lowest;
    for (int a = 0; a < p; ++a) {
        const W xa = nodes[static_cast<std::size_t>(first + a)];
        W l = 1;
        for (int b = 0; b < p; ++b) {
            if (b == a) continue;
            const W xb = nodes[static_cast<std::size_t>(first + b)];
            l *= (x - xb) / (xa - xb);
        }
        w[a] = l;
    }
    return {first, p};
}

}  // namespace stratum::detail
