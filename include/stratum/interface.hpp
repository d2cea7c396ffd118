// stratum/interface.hpp -- rough and smooth dielectric interfaces between two media.
//
// Geometry and conventions (used by every function below):
// - Local frame: z is the macro-surface normal, pointing into the medium ABOVE (index eta_above); the medium
//   below has index eta_below. Only the ratio of the indices matters.
// - Renderer-facing functions take unit vectors wi (towards the light) and wo (towards the viewer), both
//   pointing AWAY from the surface (pbrt's convention). Light travels from wi's side to wo's side: wi and wo
//   in the same hemisphere (above or below) is reflection, in opposite hemispheres transmission.
//   eta_i, eta_o below denote the indices on wi's and wo's sides.
// - All values are BSDF values per steradian, without the cosine: outgoing radiance
//   L(wo) = int f(wi, wo) L(wi) |wi.z| dwi; the hemispherical reflectance/transmittance for incidence wi are
//   int f(wi, wo) |wo.z| dwo over wo's hemisphere (power fractions; the BTDF carries the radiance factor
//   eta_o^2 / eta_i^2 of Walter et al. 2007, so no further factor appears in these integrals).
// - Degenerate input (a direction on the horizon, a refraction configuration no facet can produce) gives 0.
//
// Microfacet model (Stam 2001 Section 4, corrected as in the project's physics notes; Walter et al. 2007 form):
//   brdf  r(i, o) = F(i.h, eta_t/eta_i) D(h) G2(i, o) / (4 |i.z| |o.z|),                  h = normalize(i + o)
//   btdf  t(i, o) = |i.h| |o.h| / (|i.z| |o.z|) eta_o^2 (1 - F(i.h, eta_o/eta_i)) D(h) G2(i, o)
//                   / (eta_i (i.h) + eta_o (o.h))^2,                                     h = +-normalize(eta_i i + eta_o o)
// with D the Beckmann distribution (microfacet.hpp), normalized over projected area. Stam's paper writes the
// slope density P = D cos(theta_h) in place of D, which loses ~7% of the transmitted energy at sigma = 0.3;
// this code uses D. The denominator is Stam's refraction Jacobian (cos th'_0 - mu_t)^2 with
// mu_t = sqrt(cos^2 th'_0 + eta^2 - 1) (the paper drops both squares). The half vector h is taken on the
// side of wi (facet normals of the height field point into wi's medium as seen from wi); back-facing facets
// contribute nothing: reflection needs (i.h) > 0 and (o.h) > 0, transmission (i.h) > 0 and (o.h) < 0.
//
// Shadowing (Smith, Gaussian surface, Lambda from van Ginneken et al. 1998), chosen by `Shadowing`:
// - height_correlated (DEFAULT): reflection G2 = 1 / (1 + Lambda(i) + Lambda(o)); transmission, where masking
//   and shadowing are on opposite sides of the microsurface, G2 = B(1 + Lambda(i), 1 + Lambda(o)) with B the
//   Beta function (Heitz 2014, "Understanding the masking-shadowing function in microfacet-based BRDFs",
//   Sec. 6: a point at height-CDF value C is visible from above with probability C^Lambda(i) and from below
//   with probability (1 - C)^Lambda(o); integrating over C gives B; the same integral with C^Lambda(o) gives
//   the reflection form).
// - separable: G2 = G1(i) G1(o) for both.
// - masking_only: G2 = G1(i) (no outgoing shadowing). Not a rendering model: it is the form whose total
//   reflected + transmitted energy equals exactly the facet-scattered energy minus the part sent into the
//   wrong hemisphere; the tests use it to check the BRDF/BTDF against a facet-level Monte Carlo.
//
// Index matching (eta_above == eta_below exactly): nothing is reflected and the transmission is the identity,
// a delta in the direction -wi. brdf and btdf return 0 (a delta cannot be evaluated), sample returns the
// straight-through direction flagged as delta, hemispherical_totals returns {0, 1}. For eta_above != eta_below the BTDF is a
// proper function however close the indices are; its lobe narrows like |eta - 1| sigma and its peak grows
// like 1/(eta - 1)^2 (finite; 0 is returned only where the Jacobian denominator is exactly 0). Note that with
// shadowing the energy of that lobe tends, as eta -> 1, to E[G2 / G1(i)] < 1 (the single-scattering model
// still counts light striking a second facet as lost, although at eta = 1 that facet is invisible), so the
// exact-matching identity is the limit only for masking_only. Measured (sigma = 0.3, height-correlated):
// T(eta = 1 + 1e-9) = 0.99999992 at mu_i = 0.77, 0.80 at mu_i = 0.2, against 1 at eta = 1 exactly.
//
// Smooth limit (sigma < RoughDielectric::smooth_sigma = 1e-7, sigma = 0 included; see there for the choice):
// the interface is the smooth dielectric (SmoothDielectric). As for index matching, brdf, btdf and pdf return
// 0, sample returns the mirror or Snell direction as a delta sample chosen with probability F or 1 - F, and
// hemispherical_totals returns {F, 1 - F}. Every value is finite for every sigma >= 0 (tests/test_interface_smooth_limit.cpp).
//
// Energy (tests/test_interface_energy.cpp): with masking_only, R + T equals 1 minus the facet-scattered light
// sent into the wrong hemisphere, as measured by a facet-level Monte Carlo (e.g. 0.63% at sigma = 0.3,
// eta = 1.4, 40 deg; 2.9% at sigma = 1, 60 deg). The default shadowing loses 1 - (R + T) = 0.89% (sigma = 0.3,
// eta = 1.4, 40 deg, from above), 8.3% (same, from the dense side), 23% and 48% (sigma = 1, 60 deg, from above
// and from below). Height-correlated transmission shadows more than separable (Chebyshev's inequality:
// B(1 + a, 1 + b) <= 1 / ((1 + a)(1 + b))), reflection less.
//
// Cost: eval, brdf, btdf and pdf are a few dozen flops and one exp/erfc each; sample adds two CDF inversions
// by Newton; hemispherical_totals is a 2-D integral (see there). Measured figures: README and docs/accuracy.md.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <utility>
#include <vector>

#include "detail/config.hpp"
#include "detail/math.hpp"
#include "detail/validate.hpp"
#include "fresnel.hpp"
#include "microfacet.hpp"
#include "quadrature.hpp"
#include "vec3.hpp"

namespace stratum {

/// Joint masking-shadowing form; see the header comment. height_correlated is the default.
enum class Shadowing { height_correlated, separable, masking_only };

/// Result of RoughDielectric::sample. value = f(wi, wo) (no cosine) and pdf its solid-angle density, so the
/// Monte Carlo weight is value |wo.z| / pdf. A failed sample (direction into the wrong hemisphere, wi on the
/// horizon) has pdf = 0 and value = 0 and must be discarded. A delta sample (index-matched or smooth interface)
/// has delta = true, pdf = the probability of choosing that lobe and value = pdf / |wo.z| (the coefficient of
/// the solid-angle delta in wo), so the weight value |wo.z| / pdf is exactly the lobe's power fraction per
/// selection probability, i.e. 1:
/// - index matched: wo = -wi, pdf = 1;
/// - smooth (RoughDielectric::smooth()): mirror direction with pdf = F, or Snell direction with pdf = 1 - F
///   (F = fresnel_dielectric(|wi.z|, eta_t / eta_i); under total internal reflection the mirror, pdf = 1).
/// The weight is a power (flux) ratio, as for the rough lobes, whose weight G2 / G1(wi) tends to 1 as
/// sigma -> 0: sample() estimates int f(wi, wo) |wo.z| dwo over wo. A camera path tracer that passes the
/// viewer's direction as wi (reciprocity) must, for transmission (rough or smooth), multiply the weight by
/// (n_viewer / n_light)^2 (generalized reciprocity btdf(wi, wo) / eta_o^2 = btdf(wo, wi) / eta_i^2), the
/// radiance factor of SmoothDielectric::radiance_transmittance.
template <class Real = double>
struct BsdfSample {
    Vec3<Real> wo{};
    Real value = 0;
    Real pdf = 0;
    bool reflected = false;
    bool delta = false;
    STRATUM_HOST_DEVICE bool valid() const noexcept { return pdf > 0; }
};

/// Directional-hemispherical reflectance and transmittance (power fractions) for one incident direction.
template <class Real = double>
struct HemisphericalTotals {
    Real reflectance = 0;
    Real transmittance = 0;
};

namespace detail {

/// Joint masking-shadowing for the Smith Lambdas li (incident) and lo (outgoing), as a function of the
/// form and of whether the two directions are on opposite sides (transmission).
template <class W>
STRATUM_HOST_DEVICE W smith_g2(W li, W lo, Shadowing form, bool transmission) noexcept {
    const W inf = std::numeric_limits<W>::infinity();
    switch (form) {
        case Shadowing::masking_only: return 1 / (1 + li);
        case Shadowing::separable: return 1 / ((1 + li) * (1 + lo));
        case Shadowing::height_correlated:
        default:
            if (!transmission) return 1 / (1 + li + lo);
            if (li == inf || lo == inf) return W(0);
            // B(1 + li, 1 + lo) = Gamma(1 + li) Gamma(1 + lo) / Gamma(2 + li + lo) (thread-safe log-gammas,
            // detail/math.hpp). B <= B(1 + m, 1 + m) < 4^{-m}, m = min(li, lo): 0 in every type for m > 1e15,
            // where the log-gammas would overflow (inf - inf).
            if (!(std::fmin(li, lo) <= W(1e15))) return W(0);
            return std::exp(log_beta1(li, lo));
    }
}

/// G2 / G1(i) with G1(i) = 1 / (1 + li), finite also at li = inf (grazing incidence); used where the visible
/// normal distribution (which contains G1(i)) is the integration measure.
template <class W>
STRATUM_HOST_DEVICE W smith_g2_over_g1(W li, W lo, Shadowing form, bool transmission) noexcept {
    const W inf = std::numeric_limits<W>::infinity();
    switch (form) {
        case Shadowing::masking_only: return W(1);
        case Shadowing::separable: return 1 / (1 + lo);
        case Shadowing::height_correlated:
        default:
            if (!transmission) return li == inf ? (lo == inf ? W(0) : W(1)) : 1 / (1 + lo / (1 + li));
            if (lo == inf) return W(0);
            if (li == inf) return lo == 0 ? W(1) : W(0);
            // (1 + li) B(1 + li, 1 + lo) < (1 + li) 4^{-m}, m = min(li, lo): 0 in every type for m > 1e15.
            if (!(std::fmin(li, lo) <= W(1e15))) return W(0);
            return std::exp(std::log1p(li) + log_beta1(li, lo));
    }
}

/// Smith's Lambda of a Gaussian surface through phi(a) = a Lambda(a) = (e^{-a^2}/sqrt(pi) - a erfc(a)) / 2,
/// an entire function: a table of Taylor expansions about the centres of 24 intervals of width 1/4 covering
/// [0, 6], built once (first use) from the exact derivatives phi' = -erfc(a)/2, phi^(k+2) = (-1)^k H_k(a)
/// e^{-a^2}/sqrt(pi) (H_k Hermite polynomials). Degree 12 (16 for wider types) leaves a truncation error below
/// 3e-17 (5e-23), checked with mpmath; beyond a = 6, Lambda < 4e-19 and is returned as 0. Used where Lambda
/// is needed many times (the hemispherical_totals integral): a table lookup and a short Horner loop instead of erfc and exp.
template <class W>
class SmithLambdaTable {
public:
    static constexpr int pieces = 24;
    static constexpr int degree = std::numeric_limits<W>::digits > 53 ? 16 : 12;
    static constexpr W a_max = W(6);

    static const SmithLambdaTable& get() {
        static const SmithLambdaTable table;
        return table;
    }

    /// phi(a) = a Lambda(a) for 0 <= a < a_max (callers test a >= a_max, where Lambda is 0, themselves).
    STRATUM_HOST_DEVICE W phi(W a) const noexcept {
        const int j = std::min(static_cast<int>(a * 4), pieces - 1);
        const W t = a - (static_cast<W>(j) + W(0.5)) / 4;
        return polynomial4<W, padded>(coef_[j], t);
    }
    /// Lambda(a) for 0 < a < a_max.
    STRATUM_HOST_DEVICE W lambda(W a) const noexcept { return phi(a) / a; }

private:
    SmithLambdaTable() {
        for (int j = 0; j < pieces; ++j) {
            const W a = (static_cast<W>(j) + W(0.5)) / 4;
            const W g = std::exp(-a * a) / sqrt_pi_v<W>;
            const W ec = std::erfc(a);
            coef_[j][0] = (g - a * ec) / 2;
            coef_[j][1] = -ec / 2;
            W h_prev = 0, h = 1, factorial = 1;  // H_{m-1}, H_m with m = k - 2
            for (int k = 2; k <= degree; ++k) {
                const int m = k - 2;
                if (m > 0) {
                    const W next = 2 * a * h - 2 * static_cast<W>(m - 1) * h_prev;
                    h_prev = h;
                    h = next;
                }
                factorial *= static_cast<W>(k);
                coef_[j][k] = (k % 2 != 0 ? -h : h) * g / factorial;
            }
        }
    }
    static constexpr int padded = (degree + 4) / 4 * 4;  // degree + 1 coefficients, zero-padded
    W coef_[pieces][padded] = {};
};

/// Gauss-Legendre rules on [0, 1] for n = 1..max_n, computed once (first use) into fixed arrays.
template <class W>
class HalfRuleTable {
public:
    static constexpr int max_n = 32;
    static const HalfRuleTable& get() {
        static const HalfRuleTable table;
        return table;
    }
    STRATUM_HOST_DEVICE const W* nodes(int n) const noexcept { return nodes_[n]; }
    STRATUM_HOST_DEVICE const W* weights(int n) const noexcept { return weights_[n]; }

private:
    HalfRuleTable() {
        for (int n = 1; n <= max_n; ++n) {
            const Quadrature<W> q = gauss_legendre_half<W>(n);
            for (int i = 0; i < n; ++i) {
                nodes_[n][i] = q.nodes[static_cast<std::size_t>(i)];
                weights_[n][i] = q.weights[static_cast<std::size_t>(i)];
            }
        }
    }
    W nodes_[max_n + 1][max_n] = {};
    W weights_[max_n + 1][max_n] = {};
};

/// Digamma psi(x) and trigamma psi'(x) for x >= 1: recurrence to x >= 10, then the asymptotic series.
template <class W>
STRATUM_HOST_DEVICE void digamma_trigamma(W x, W& psi, W& psi1) noexcept {
    W a = 0, b = 0;
    while (x < W(10)) {
        a -= 1 / x;
        b += 1 / (x * x);
        x += 1;
    }
    const W r = 1 / x, r2 = r * r;
    psi = a + std::log(x) - r / 2 - r2 * (W(1) / 12 - r2 * (W(1) / 120 - r2 * (W(1) / 252 - r2 * (W(1) / 240))));
    psi1 = b + r + r2 / 2 + r * r2 * (W(1) / 6 - r2 * (W(1) / 30 - r2 * (W(1) / 42 - r2 * (W(1) / 30))));
}

/// Hurwitz zeta(k, x) = sum_{j >= 0} (x + j)^{-k} for k = 2..K (written to out[k]), x >= 1: ten terms, then
/// the Euler-Maclaurin tail at a = x + 10, a^{1-k}/(k-1) + a^{-k}/2 + sum_{m=1..4} B_2m/(2m)! (k)_{2m-1}
/// a^{-k-2m+1} (relative error < 1e-19 for k <= 20).
template <class W>
STRATUM_HOST_DEVICE void hurwitz_zeta(W x, int K, W* out) noexcept {
    for (int k = 2; k <= K; ++k) out[k] = 0;
    for (int j = 0; j < 10; ++j) {
        const W inv = 1 / (x + static_cast<W>(j));
        W p = inv;
        for (int k = 2; k <= K; ++k) {
            p *= inv;
            out[k] += p;
        }
    }
    const W a = x + 10, r = 1 / a, r2 = r * r;
    W ak = r;  // a^{-k}
    for (int k = 2; k <= K; ++k) {
        ak *= r;
        const W kk = static_cast<W>(k);
        const W t1 = kk * r / 12;
        const W t2 = -kk * (kk + 1) * (kk + 2) * r * r2 / 720;
        const W t3 = kk * (kk + 1) * (kk + 2) * (kk + 3) * (kk + 4) * r * r2 * r2 / 30240;
        const W t4 = -kk * (kk + 1) * (kk + 2) * (kk + 3) * (kk + 4) * (kk + 5) * (kk + 6) * r * r2 * r2 * r2 / 1209600;
        out[k] += ak * (a / (kk - 1) + W(0.5) + t1 + t2 + t3 + t4);
    }
}

/// Hemispherical reflectance and transmittance of a rough dielectric for incidence from above with cosine
/// mu in [0, 1], relative index eta = eta_t / eta_i. With wi = (s, 0, mu), facet slopes X = alpha x,
/// Y = alpha y (alpha = 1 units x, y) and m = (-X, -Y, 1):
///   R = int int e^{-x^2-y^2} / (pi A(mu)) (mu - s X)_+ F(c) [G2/G1(i)](o_r) [o_r.z > 0] dx dy,
///   T = the same with (1 - F(c)) and the refracted direction o_t, [o_t.z < 0],
/// c = (mu - s X)/|m|, A(mu) = mu (1 + Lambda(mu)) the visible projected area (Beckmann::projected_area).
/// The integrand is analytic except on a few curves, all conics in (X, Y):
///   reflected direction on the horizon    mu X^2 + 2 s X + mu (Y^2 - 1) = 0,
///   refracted direction on the horizon    mu^2 X^2 + 2 mu s X + mu^2 (Y^2 - 1) - (eta^2 - 1) = 0
///                                         (from squaring eta cos_t = c - mu |m|: only where mu |m|^2 + s X <= 0),
///   critical angle (eta < 1, c_c^2 = 1 - eta^2)   (s^2 - c_c^2) X^2 - 2 mu s X + mu^2 - c_c^2 (1 + Y^2) = 0,
/// the back-facing edge X = mu / s, and two points where Lambda(o) ~ exp(-k / r^2) is smooth but not analytic:
/// the facets sending o_r or o_t along the normal, (X, Y) = (-s / (1 + mu), 0) and (s / (eta - mu), 0).
/// The last two conics are tangent (eliminating Y^2 gives a double root) at X = -(c_c^2 - mu^2) / (mu s).
/// For each y the x range [-L, x_max] is split at the roots and points, and the y range [0, L] (the
/// integrand is even in y) where two roots merge, cross, touch or cross x_max; L = 5.5 truncates the Gaussian
/// (e^{-L^2} < 1e-13). Singular panel ends get the map t -> t^2 (3t^2 - 2t^3 at both ends), which turns
/// square-root onsets into smooth behaviour; when a square-root point lies just beyond a panel end whose own
/// singularity is a mere jump, the map is centred on that point instead; next to a pair of close branch
/// points the panels are graded geometrically. Movable breakpoints grade the panels towards the complex
/// singularities at X = +-i sqrt(1 + Y^2) (for large alpha) and limit them to 2 Gaussian units; one that
/// would leave a sliver next to a breakpoint of higher rank is dropped. Gauss-Legendre with n nodes per
/// x panel and 3n/4 per y panel, fewer on panels whose Gaussian mass bound is small (none below 1e-11).
/// The shadowing factors use SmithLambdaTable, and the height-correlated transmission factor
/// (1 + li) B(1 + li, 1 + lo) its Taylor series in lo (lo < 1/16) or log_gamma_ratio.
template <class W>
HemisphericalTotals<W> rough_hemispherical_totals(W sigma, W mu, W eta, Shadowing form, int n) {
    const Beckmann<W> dist(sigma);
    const SmithLambdaTable<W>& lambda_table = SmithLambdaTable<W>::get();
    const HalfRuleTable<W>& rules = HalfRuleTable<W>::get();
    const W alpha = dist.alpha();
    const W s = std::sqrt((1 - mu) * (1 + mu));
    const W L = W(5.5);
    const W x_edge = s > 0 ? mu / (alpha * s) : std::numeric_limits<W>::infinity();  // back-facing edge
    const W x_max = std::fmin(x_edge, L);
    const W li = dist.Lambda(mu);
    const W norm = 2 / (pi_v<W> * dist.projected_area(mu));  // 2: y in [0, L] only
    const W k2 = (eta - 1) * (eta + 1);
    const W inv_eta = 1 / eta;
    const int n_x = n, n_y = (3 * n + 3) / 4;

    // Shadowing factors G2/G1(i) as functions of the outgoing cosine o in (0, 1] (on its own side).
    const W a_cut2 = SmithLambdaTable<W>::a_max * SmithLambdaTable<W>::a_max * alpha * alpha;
    auto lambda_o = [&](W o) -> W {
        const W r2 = (1 - o) * (1 + o);
        if (o * o >= a_cut2 * r2) return W(0);  // a = o / (alpha sqrt(1 - o^2)) >= a_max
        return lambda_table.lambda(o / (alpha * std::sqrt(r2)));
    };
    const W one_li = 1 + li;
    const bool li_inf = !(li < std::numeric_limits<W>::infinity());  // mu = 0
    const bool li_big = !(li < W(1000));
    // Height-correlated transmission factor beta(lo) = (1 + li) B(1 + li, 1 + lo); beta(0) = 1. Its logarithm
    // is f(lo) - f(0), f(lo) = lnGamma(1 + lo) - lnGamma(2 + li + lo), whose Taylor coefficients are
    // c_1 = psi(1) - psi(2 + li), c_k = (-1)^k [zeta(k, 1) - zeta(k, 2 + li)] / k (Hurwitz zeta); beta's own
    // series follows by the exponential recurrence b_n = (1/n) sum_k k c_k b_{n-k}. Both have radius 1 (the
    // pole of Gamma(1 + lo) at lo = -1): 16 terms for lo < 1/16 leave < 1e-19; above, log_gamma_ratio.
    constexpr int beta_terms = 16;
    const W beta_series_max = W(0.0625);
    constexpr int beta_padded = (beta_terms + 4) / 4 * 4;
    W beta_log0 = 0, beta_coef[beta_padded] = {};
    if (!li_big) {
        beta_log0 = std::log1p(li) + log_gamma(one_li);
        W c[beta_terms + 1] = {};
        W psi, psi1;
        digamma_trigamma(2 + li, psi, psi1);
        c[1] = W(-0.5772156649015328606065120900824024L) - psi;  // psi(1) - psi(2 + li)
        W zeta_1[beta_terms + 1], zeta_b[beta_terms + 1];
        hurwitz_zeta(W(1), beta_terms, zeta_1);
        hurwitz_zeta(2 + li, beta_terms, zeta_b);
        for (int k = 2; k <= beta_terms; ++k) {
            const W diff = zeta_1[k] - zeta_b[k];
            c[k] = (k % 2 == 0 ? diff : -diff) / static_cast<W>(k);
        }
        beta_coef[0] = 1;
        for (int m = 1; m <= beta_terms; ++m) {
            W acc = 0;
            for (int k = 1; k <= m; ++k) acc += static_cast<W>(k) * c[k] * beta_coef[m - k];
            beta_coef[m] = acc / static_cast<W>(m);
        }
    }
    auto shadow_reflected = [&](W o) -> W {
        // 1 / (1 + lo) = a / (a + phi(a)) and (1 + li) / (1 + li + lo) = (1 + li) a / ((1 + li) a + phi(a)).
        if (form == Shadowing::masking_only) return W(1);
        const W r2 = (1 - o) * (1 + o);
        if (o * o >= a_cut2 * r2) return W(1);  // lo = 0
        const W a = o / (alpha * std::sqrt(r2)), ph = lambda_table.phi(a);
        if (form == Shadowing::separable) return a / (a + ph);
        return li_inf ? W(1) : one_li * a / (one_li * a + ph);
    };
    auto shadow_transmitted = [&](W o) -> W {
        if (form == Shadowing::masking_only) return W(1);
        const W lo = lambda_o(o);
        if (form == Shadowing::separable) return 1 / (1 + lo);
        // li = inf: (1 + li)^{-lo} -> 0 for every lo > 0 (o = 1 exactly has measure zero).
        if (li_inf || !(lo < W(1e15))) return W(0);
        if (lo == 0) return W(1);
        if (li_big) return std::exp(log_gamma(1 + lo) + log_gamma_ratio(2 + li, lo));
        if (lo < beta_series_max) {
            return polynomial4<W, beta_padded>(beta_coef, lo);
        }
        return std::exp(beta_log0 + log_gamma_ratio(1 + lo, one_li));
    };

    // Conics A X^2 + B X + C0 + C2 Y^2 = 0: 0 reflected horizon, 1 refracted horizon, 2 critical angle.
    struct Conic { W A, B, C0, C2; };
    Conic conics[3] = {{mu, 2 * s, -mu, mu}, {mu * mu, 2 * mu * s, -mu * mu - k2, mu * mu}, {}};
    int nc = 2;
    if (eta < 1) {
        const W cc2 = -k2;
        conics[nc++] = {s * s - cc2, -2 * mu * s, mu * mu - cc2, -cc2};
    }
    // Roots of conic 1 with c - mu |m| < 0 (mu (X^2 + Y^2) + s X > 0) are artefacts of the squaring.
    auto genuine = [&](int conic, W X, W Y2) {
        if (conic != 1) return true;
        const W a = mu * (X * X + Y2), b = s * X;
        return a + b <= W(1e-7) * (a + std::fabs(b));
    };

    // Breakpoints. rank: 0 = fixed (never dropped), 1 = grid, 2 = grading towards the edge for eta ~ 1.
    // singular: the integrand (or the inner integral) is not analytic there; branch: it has a branch point
    // there (not a mere jump), felt by the neighbouring panels; strong: a square-root branch point.
    struct Break {
        W at;
        bool singular;
        int rank;
        bool branch;
        bool strong;
    };
    constexpr int capacity = 96;
    auto sort_breaks = [](Break* b, int count) {
        for (int i = 1; i < count; ++i)
            for (int j = i; j > 0 && b[j].at < b[j - 1].at; --j) std::swap(b[j], b[j - 1]);
        int out = 0;
        for (int i = 0; i < count; ++i) {
            const W tol = 64 * std::numeric_limits<W>::epsilon() * std::fmax(W(1), std::fabs(b[i].at));
            if (out > 0 && b[i].at - b[out - 1].at <= tol) {
                Break& m = b[out - 1];
                m.singular = m.singular || b[i].singular;
                m.branch = m.branch || b[i].branch;
                m.strong = m.strong || b[i].strong;
                m.rank = m.singular || m.rank == 0 || b[i].rank == 0 ? 0 : std::max(m.rank, b[i].rank);
            } else {
                b[out++] = b[i];
            }
        }
        // A movable breakpoint closer to a neighbour of higher rank than a quarter of its distance to the
        // other neighbour would leave a sliver panel next to a long one: drop it.
        auto rank_of = [](const Break& q) { return q.singular || q.rank == 0 ? 1000 : q.rank; };
        for (int pass = 0; pass < 3; ++pass) {
            int kept = 0;
            for (int i = 0; i < out; ++i) {
                if (rank_of(b[i]) < 1000 && kept > 0 && i + 1 < out) {
                    const W dl = b[i].at - b[kept - 1].at, dr = b[i + 1].at - b[i].at;
                    if ((dl < dr / 4 && rank_of(b[kept - 1]) > b[i].rank) || (dr < dl / 4 && rank_of(b[i + 1]) > b[i].rank))
                        continue;
                }
                b[kept++] = b[i];
            }
            if (kept == out) break;
            out = kept;
        }
        return out;
    };
    // Geometric grading (ratio 4) away from a pair of close branch points, so that no panel sees a branch
    // point just beyond its end; pairs closer than 1e-11 of the panel act as one point.
    auto grade_pairs = [](Break* b, int count) {
        Break extra[32];
        int ne = 0;
        for (int i = 0; i + 1 < count; ++i) {
            if (!(b[i].singular && b[i + 1].singular && b[i].branch && b[i + 1].branch)) continue;
            const W delta = b[i + 1].at - b[i].at;
            if (i > 0) {
                const W d = b[i].at - b[i - 1].at;
                if (delta < d / 4 && delta > W(1e-11) * d)
                    for (W g = 2 * delta; g < d / 2 && ne < 32; g *= 4) extra[ne++] = {b[i].at - g, false, 0, false, false};
            }
            if (i + 2 < count) {
                const W d = b[i + 2].at - b[i + 1].at;
                if (delta < d / 4 && delta > W(1e-11) * d)
                    for (W g = 2 * delta; g < d / 2 && ne < 32; g *= 4) extra[ne++] = {b[i + 1].at + g, false, 0, false, false};
            }
        }
        if (ne == 0) return count;
        for (int k = 0; k < ne && count < capacity; ++k) b[count++] = extra[k];
        for (int i = 1; i < count; ++i)
            for (int j = i; j > 0 && b[j].at < b[j - 1].at; --j) std::swap(b[j], b[j - 1]);
        return count;
    };
    // Grid: symmetric about 0, first at min(R / (2 alpha), 1) (R / alpha: distance of the complex
    // singularities), then spacing doubling up to 2 (the Gaussian's scale).
    auto add_grid = [&](Break* b, int& count, W lo, W hi, W R) {
        W p = std::fmin(R / (2 * alpha), W(1));
        while (p < L && count + 2 <= capacity / 2) {
            if (p > lo && p < hi) b[count++] = {p, false, 1, false, false};
            if (-p > lo && -p < hi) b[count++] = {-p, false, 1, false, false};
            p += std::fmin(p, W(2));
        }
    };
    // Nodes for a panel from its Gaussian mass bound (length times the largest e^{-x^2}): the base count
    // for mass >= 1, proportionally fewer down to 4 as the mass falls towards 1e-11, none below.
    const W mass_floor = W(1e-11), log_floor = std::log(mass_floor);
    auto nodes_for = [&](W lo, W hi, int base) -> int {
        const W m0 = lo > 0 ? lo : (hi < 0 ? -hi : W(0));
        const W mass = (hi - lo) * std::exp(-m0 * m0);
        if (!(mass > mass_floor)) return 0;
        const W frac = std::fmin(W(1), 1 - std::log(mass) / log_floor);
        const int k = static_cast<int>(std::ceil(static_cast<W>(base) * frac));
        return std::max(4, k);
    };
    // Panel i of the sorted breakpoints b[0..count), with `base` nodes at most.
    auto panel = [&](const Break* b, int count, int i, int base, auto&& body) {
        const Break& lo = b[i];
        const Break& hi = b[i + 1];
        const W d = hi.at - lo.at;
        if (!(d > 0)) return;
        const int m = nodes_for(lo.at, hi.at, base);
        if (m == 0) return;
        const W* ts = rules.nodes(m);
        const W* ws = rules.weights(m);
        W c_lo = lo.at, c_hi = hi.at;  // centres of the maps
        if (lo.singular && !lo.strong && i > 0 && b[i - 1].strong && lo.at - b[i - 1].at < d / 4) c_lo = b[i - 1].at;
        if (hi.singular && !hi.strong && i + 2 < count && b[i + 2].strong && b[i + 2].at - hi.at < d / 4)
            c_hi = b[i + 2].at;
        const W D = c_hi - c_lo;
        if (lo.singular && hi.singular) {
            // x = c_lo + D g(u), g(u) = 3u^2 - 2u^3, u in [ua, ub] (x(ua) = lo, x(ub) = hi).
            auto inverse = [](W target) {
                if (target <= 0) return W(0);
                if (target >= 1) return W(1);
                W u = target < W(0.5) ? std::sqrt(target / 3) : 1 - std::sqrt((1 - target) / 3);
                for (int it = 0; it < 6; ++it) {
                    const W g = u * u * (3 - 2 * u) - target, dg = 6 * u * (1 - u);
                    if (!(dg > 0)) break;
                    u -= g / dg;
                }
                return u;
            };
            const W ua = c_lo == lo.at ? W(0) : inverse((lo.at - c_lo) / D);
            const W ub = c_hi == hi.at ? W(1) : inverse((hi.at - c_lo) / D);
            const W du = ub - ua;
            for (int k = 0; k < m; ++k) {
                const W u = ua + du * ts[k];
                body(c_lo + D * u * u * (3 - 2 * u), ws[k] * du * 6 * D * u * (1 - u));
            }
        } else if (lo.singular) {
            const W ua = c_lo == lo.at ? W(0) : std::sqrt((lo.at - c_lo) / D);  // x = c_lo + D u^2
            const W du = 1 - ua;
            for (int k = 0; k < m; ++k) {
                const W u = ua + du * ts[k];
                body(c_lo + D * u * u, ws[k] * du * 2 * D * u);
            }
        } else if (hi.singular) {
            const W ub = c_hi == hi.at ? W(0) : std::sqrt((c_hi - hi.at) / D);  // x = c_hi - D u^2
            const W du = 1 - ub;
            for (int k = 0; k < m; ++k) {
                const W u = ub + du * ts[k];
                body(c_hi - D * u * u, ws[k] * du * 2 * D * u);
            }
        } else {
            for (int k = 0; k < m; ++k) body(lo.at + d * ts[k], ws[k] * d);
        }
    };

    // y breakpoints: where roots merge, cross x_max, cross each other or touch.
    Break ybreak[capacity];
    int ny = 0;
    ybreak[ny++] = {W(0), false, 0, false, false};
    ybreak[ny++] = {L, false, 0, false, false};
    add_grid(ybreak, ny, W(0), L, W(1));
    auto add_y = [&](W Y2) {
        if (Y2 > 0 && ny < capacity - 32) {
            const W y = std::sqrt(Y2) / alpha;
            if (y < L) ybreak[ny++] = {y, true, 0, true, true};
        }
    };
    auto in_x = [&](W X) { return X / alpha < x_max && X / alpha > -L; };
    for (int i = 0; i < nc; ++i) {
        const Conic& q = conics[i];
        if (q.C2 == 0) continue;
        if (q.A != 0) {
            const W X = -q.B / (2 * q.A), Y2 = (q.B * q.B / (4 * q.A) - q.C0) / q.C2;
            if (in_x(X) && genuine(i, X, Y2)) add_y(Y2);
        }
        if (x_edge < L) {
            const W X = alpha * x_edge, Y2 = -(q.A * X * X + q.B * X + q.C0) / q.C2;
            if (genuine(i, X, Y2)) add_y(Y2);
        }
    }
    for (int i = 0; i < nc; ++i) {
        for (int k = i + 1; k < nc; ++k) {
            if (i == 1 && k == 2) continue;  // tangent: added below
            const Conic &p = conics[i], &q = conics[k];
            if (p.C2 == 0) continue;
            const W r = q.C2 / p.C2;
            const W A = q.A - r * p.A, B = q.B - r * p.B, C = q.C0 - r * p.C0;
            W roots[2];
            int nr = 0;
            if (A == 0) {
                if (B != 0) roots[nr++] = -C / B;
            } else {
                const W disc = B * B - 4 * A * C;
                if (disc >= 0) {
                    const W qq = -(B + std::copysign(std::sqrt(disc), B)) / 2;
                    roots[nr++] = qq / A;
                    if (qq != 0) roots[nr++] = C / qq;
                }
            }
            for (int m = 0; m < nr; ++m) {
                const W X = roots[m], Y2 = -(p.A * X * X + p.B * X + p.C0) / p.C2;
                if (in_x(X) && genuine(i, X, Y2) && genuine(k, X, Y2)) add_y(Y2);
            }
        }
    }
    if (eta < 1 && mu > 0 && s > 0) {
        const W X = -(-k2 - mu * mu) / (mu * s);
        const Conic& q = conics[1];
        if (in_x(X)) add_y(-(q.A * X * X + q.B * X + q.C0) / q.C2);
    }
    ny = sort_breaks(ybreak, ny);
    ny = grade_pairs(ybreak, ny);

    const bool near_one = k2 != 0 && std::fabs(k2) < W(0.25);
    const bool lambda_points = form != Shadowing::masking_only;
    W R = 0, T = 0;
    auto row = [&](W y, W wy) {
        const W Y = alpha * y, Y2 = Y * Y;
        Break xb[capacity];
        int nx = 0;
        xb[nx++] = {-L, false, 0, false, false};
        xb[nx++] = {x_max, x_max == x_edge, 0, false, false};
        add_grid(xb, nx, -L, x_max, std::sqrt(1 + Y2));
        // eta ~ 1: F(c) has branch points at c = +-i sqrt(eta^2 - 1), close to the back-facing edge c = 0:
        // grade geometrically towards the edge down to that scale.
        if (x_max == x_edge && near_one) {
            const W scale = std::sqrt(std::fabs(k2)) * std::sqrt(1 + alpha * alpha * x_edge * x_edge + Y2) / (s * alpha);
            for (W d = scale / 2; d < W(0.5) / alpha && nx < capacity / 2; d *= 2)
                if (x_edge - d > -L) xb[nx++] = {x_edge - d, false, 2, false, false};
        }
        for (int i = 0; i < nc; ++i) {
            const Conic& q = conics[i];
            const W C = q.C0 + q.C2 * Y2;
            W r[2];
            int nr = 0;
            if (q.A == 0) {
                if (q.B != 0) r[nr++] = -C / q.B;
            } else {
                const W disc = q.B * q.B - 4 * q.A * C;
                if (disc >= 0) {
                    const W qq = -(q.B + std::copysign(std::sqrt(disc), q.B)) / 2;
                    if (qq != 0) {
                        r[nr++] = qq / q.A;
                        r[nr++] = C / qq;
                    } else {
                        r[nr++] = 0;
                    }
                }
            }
            // The critical angle is a square-root branch point of F; the refracted horizon one of the
            // height-correlated factor ~ a^{1 + li}; the reflected horizon only a jump.
            const bool branch = i == 2 || (i == 1 && form == Shadowing::height_correlated);
            for (int k = 0; k < nr; ++k) {
                const W x = r[k] / alpha;
                if (x > -L && x < x_max && genuine(i, r[k], Y2)) xb[nx++] = {x, true, 0, branch, i == 2};
            }
        }
        if (lambda_points) {
            const W xr = -s / ((1 + mu) * alpha);
            if (xr > -L && xr < x_max) xb[nx++] = {xr, true, 0, true, true};
            if (eta * mu > 1) {
                const W xt = s / ((eta - mu) * alpha);
                if (xt > -L && xt < x_max) xb[nx++] = {xt, true, 0, true, true};
            }
        }
        nx = sort_breaks(xb, nx);
        nx = grade_pairs(xb, nx);
        W r_sum = 0, t_sum = 0;
        for (int i = 0; i + 1 < nx; ++i)
            panel(xb, nx, i, n_x, [&](W x, W wx) {
                const W X = alpha * x;
                const W proj = mu - s * X;
                if (!(proj > 0)) return;
                const W inv_len = 1 / std::sqrt(1 + X * X + Y2);
                const W c = proj * inv_len;
                const W w = wx * std::exp(-x * x) * proj;
                const W F = fresnel_dielectric(c, eta);
                const W or_z = 2 * c * inv_len - mu;
                if (or_z > 0 && F > 0) r_sum += w * F * shadow_reflected(or_z);
                const W sin2_t = (1 - c) * (1 + c) * inv_eta * inv_eta;
                if (sin2_t < 1 && F < 1) {
                    const W cos_t = std::sqrt(1 - sin2_t);
                    const W ot_z = (c * inv_eta - cos_t) * inv_len - mu * inv_eta;
                    if (ot_z < 0) t_sum += w * (1 - F) * shadow_transmitted(-ot_z);
                }
            });
        const W g = wy * std::exp(-y * y);
        R += g * r_sum;
        T += g * t_sum;
    };
    for (int j = 0; j + 1 < ny; ++j) panel(ybreak, ny, j, n_y, row);
    return {R * norm, T * norm};
}

}  // namespace detail

/// Rough dielectric interface: a Gaussian microsurface of RMS slope sigma between media of indices
/// eta_above (z > 0) and eta_below. All evaluation functions are noexcept and allocation-free.
/// sigma = 0 (and any sigma below smooth_sigma) is the smooth limit: see smooth().
template <class Real = double>
class RoughDielectric {
public:
    /// Below this RMS slope the interface is treated as exactly smooth (smooth()). The same value for every
    /// type, chosen above every arithmetic limit and below anything physical:
    /// - arithmetic: D's peak 1 / (2 pi sigma^2) and the BTDF and pdf peaks, which grow like
    ///   eta_o^2 / ((eta_o - eta_i)^2 sigma^2) (eta_o, eta_i adjacent floating-point numbers at worst), are
    ///   Real values (D and pdf are computed in Real; Lambda, the brdf/btdf products, sampling and albedo in
    ///   detail::wide_t). They overflow for sigma below ~8.5e-139 in double (3e-155 for D alone) and ~1.8e-13
    ///   in float (2.2e-20 for D alone). Meaning is lost earlier in float: a unit vector resolves
    ///   ~2^-24 = 6e-8 rad, so a lobe narrower than ~1e-7 lies within an ulp or two of its centre and its
    ///   values at representable directions are noise.
    /// - physical: a geometric-optics lobe narrower than the diffraction limit lambda / L means nothing; at
    ///   lambda = 0.5 um that is 1e-7 rad for a 5 m patch. Polished surfaces have RMS slopes >= ~1e-4, and no
    ///   renderer resolves 1e-7 rad (a 4K image of a 1 degree field has 4e-6 rad pixels).
    /// Continuity (tests/test_interface_smooth_limit.cpp): at sigma = smooth_sigma the rough albedo equals the
    /// Fresnel values within 1.9e-9 (the quadrature's error; the model's own difference is O(sigma^2) = 1e-14)
    /// at cosines 1e-3 or more from grazing and from a critical angle; within 1e-3 of a critical cosine the
    /// square-root onset of F is smeared by O(sqrt(sigma)) (1.1e-3 at n 1 | 1.5, 6e-3 at 1 | 1.0001).
    static constexpr Real smooth_sigma = Real(1) / Real(10000000);  // 1e-7 correctly rounded in every type
    /// The largest RMS slope accepted, 1e10 (facets within 1e-10 rad of vertical): hemispherical_totals() keeps its 1e-8
    /// accuracy up to it (measured 1e-11 at 1e10), not beyond (3e-6 at sigma = 1e140, found by fuzz_pointwise).
    static constexpr Real max_sigma = Real(1e10);

    /// sigma: RMS slope in [0, max_sigma] (0: the smooth limit); eta_above, eta_below: refractive indices in
    /// [1e-4, 1e4]. Throws std::invalid_argument naming the offending parameter.
    RoughDielectric(Real sigma, Real eta_above, Real eta_below, Shadowing shadowing = Shadowing::height_correlated)
        : sigma_(detail::require_closed("sigma", sigma, Real(0), max_sigma)),
          distribution_(sigma_ < smooth_sigma ? smooth_sigma : sigma_),
          eta_above_(detail::require_refractive_index("eta_above", eta_above)),
          eta_below_(detail::require_refractive_index("eta_below", eta_below)),
          shadowing_(shadowing) {}

    /// The Beckmann distribution of the facets. For a smooth interface (smooth()) a placeholder of RMS slope
    /// smooth_sigma, which this class never evaluates (Beckmann needs sigma > 0).
    STRATUM_HOST_DEVICE const Beckmann<Real>& distribution() const noexcept { return distribution_; }
    /// The RMS slope as constructed (0 allowed).
    STRATUM_HOST_DEVICE Real sigma() const noexcept { return sigma_; }
    STRATUM_HOST_DEVICE Real eta_above() const noexcept { return eta_above_; }
    STRATUM_HOST_DEVICE Real eta_below() const noexcept { return eta_below_; }
    STRATUM_HOST_DEVICE Shadowing shadowing() const noexcept { return shadowing_; }
    /// True when eta_above == eta_below exactly: the interface is invisible (see the header comment).
    STRATUM_HOST_DEVICE bool index_matched() const noexcept { return eta_above_ == eta_below_; }
    /// True when sigma < smooth_sigma (sigma = 0 included): the interface is the smooth dielectric, a specular
    /// reflector and refractor. brdf, btdf, eval and pdf return 0 (a delta cannot be evaluated); sample returns
    /// the mirror or Snell direction as a delta sample (see BsdfSample); hemispherical_totals returns the Fresnel values
    /// {F, 1 - F}, exactly SmoothDielectric's. Index matching takes precedence (identity transmission).
    STRATUM_HOST_DEVICE bool smooth() const noexcept { return sigma_ < smooth_sigma; }

    /// BRDF r(wi, wo) for wi, wo in the same hemisphere (either one); 0 otherwise, for index matching and
    /// for a smooth interface.
    /// Symmetric, brdf(wi, wo) == brdf(wo, wi), for every shadowing model but Shadowing::masking_only.
    STRATUM_HOST_DEVICE Real brdf(Vec3<Real> wi, Vec3<Real> wo) const noexcept {
        if (!(wi.z * wo.z > 0) || index_matched() || smooth()) return Real(0);
        const bool below = wi.z < 0;
        if (below) {
            wi.z = -wi.z;
            wo.z = -wo.z;
        }
        const Real eta_i = below ? eta_below_ : eta_above_, eta_t = below ? eta_above_ : eta_below_;
        const Vec3<Real> sum = wi + wo;
        const Real len2 = dot(sum, sum);
        if (!(len2 > 0)) return Real(0);
        const Vec3<Real> h = (Real(1) / std::sqrt(len2)) * sum;
        const Real c = dot(wi, h);
        if (!(c > 0) || !(dot(wo, h) > 0)) return Real(0);
        const Real D = distribution_.D(h);
        if (!(D > 0)) return Real(0);  // (spares the Lambdas, and 0 * inf at grazing directions)
        const Real F = fresnel_dielectric(c, eta_t / eta_i);
        using W = detail::wide_t<Real>;
        return static_cast<Real>(static_cast<W>(F) * static_cast<W>(D) * g2_over_cosines(wi.z, wo.z, false) / 4);
    }

    /// BTDF t(wi, wo) for wi, wo in opposite hemispheres (light from wi's medium into wo's medium); 0 for
    /// the same hemisphere, for configurations no facet refracts, for index matching and for a smooth
    /// interface (deltas).
    /// Generalized reciprocity: btdf(wi, wo) / eta_o^2 == btdf(wo, wi) / eta_i^2.
    STRATUM_HOST_DEVICE Real btdf(Vec3<Real> wi, Vec3<Real> wo) const noexcept {
        if (!(wi.z * wo.z < 0) || index_matched() || smooth()) return Real(0);
        const bool below = wi.z < 0;
        if (below) {
            wi.z = -wi.z;
            wo.z = -wo.z;
        }
        const Real eta_i = below ? eta_below_ : eta_above_, eta_o = below ? eta_above_ : eta_below_;
        Vec3<Real> v = eta_i * wi + eta_o * wo;
        const Real len2 = dot(v, v);
        if (!(len2 > 0)) return Real(0);
        Vec3<Real> h = (Real(1) / std::sqrt(len2)) * v;
        if (h.z < 0) h = -h;
        const Real ci = dot(wi, h), co = dot(wo, h);
        if (!(ci > 0) || !(co < 0)) return Real(0);
        const Real D = distribution_.D(h);
        if (!(D > 0)) return Real(0);  // (spares the Lambdas, and 0 * inf at grazing directions)
        const Real F = fresnel_dielectric(ci, eta_o / eta_i);
        // (eta_i (i.h) + eta_o (o.h))^2 == |v|^2, since h = +-v / |v|. The product in the wide type: for float
        // its factors can leave float's range at grazing directions although the value does not.
        using W = detail::wide_t<Real>;
        const W eo = eta_o;
        return static_cast<Real>(static_cast<W>(ci) * static_cast<W>(-co) * eo * eo * static_cast<W>(1 - F) *
                                 static_cast<W>(D) * g2_over_cosines(wi.z, -wo.z, true) / static_cast<W>(len2));
    }

    /// brdf or btdf, whichever the hemispheres of wi and wo call for.
    STRATUM_HOST_DEVICE Real eval(Vec3<Real> wi, Vec3<Real> wo) const noexcept {
        return wi.z * wo.z > 0 ? brdf(wi, wo) : btdf(wi, wo);
    }

    /// The BSDF for directions given as PROPAGATION directions, the form a radiative-transfer solver uses.
    ///   mu_in:    cosine (to +z) of the incident propagation direction; mu_in < 0 is light travelling down,
    ///             i.e. arriving from above (wi = -incident propagation direction).
    ///   mu_out:   cosine of the outgoing propagation direction (mu_out > 0: leaving upwards).
    ///   cos_dphi: cosine of the azimuth difference between the two propagation directions, so specular
    ///             reflection and refraction lie at dphi = 0.
    /// Returns f (per steradian, cosine NOT included); mu_in * mu_out > 0 is transmission, < 0 reflection.
    STRATUM_HOST_DEVICE Real eval_propagation(Real mu_in, Real mu_out, Real cos_dphi) const noexcept {
        const Real s_in = std::sqrt(std::fmax(Real(0), (1 - mu_in) * (1 + mu_in)));
        const Real s_out = std::sqrt(std::fmax(Real(0), (1 - mu_out) * (1 + mu_out)));
        const Real c = std::fmin(std::fmax(cos_dphi, Real(-1)), Real(1));
        const Real s = std::sqrt((1 - c) * (1 + c));
        const Vec3<Real> wi{-s_in, Real(0), -mu_in};
        const Vec3<Real> wo{s_out * c, s_out * s, mu_out};
        return eval(wi, wo);
    }

    /// Samples wo given wi: a facet normal from the visible-normal distribution of wi (three uniforms
    /// u_lobe, u1, u2 in [0, 1)), then reflection with probability F and refraction otherwise. See
    /// BsdfSample for the meaning of the result; value and pdf are those of eval and pdf at (wi, wo).
    /// Smooth interface (smooth()): the mirror direction if u_lobe < F(|wi.z|) (always under total internal
    /// reflection), else the Snell direction, as a delta sample (u1, u2 unused).
    STRATUM_HOST_DEVICE BsdfSample<Real> sample(Vec3<Real> wi, Real u_lobe, Real u1, Real u2) const noexcept {
        BsdfSample<Real> out;
        if (!(wi.z != 0)) return out;
        if (index_matched()) {
            out.wo = -wi;
            out.delta = true;
            out.pdf = Real(1);
            out.value = Real(1) / std::fabs(wi.z);
            return out;
        }
        const bool below = wi.z < 0;
        const Real eta_i = below ? eta_below_ : eta_above_, eta_t = below ? eta_above_ : eta_below_;
        if (smooth()) return sample_smooth(wi, eta_t / eta_i, u_lobe);
        Vec3<Real> w = wi;
        if (below) w.z = -w.z;
        const Vec3<Real> h = distribution_.sample_visible_normal(w, u1, u2);
        const Real c = dot(w, h);
        if (!(c > 0)) return out;
        const Real eta = eta_t / eta_i;
        const Real F = fresnel_dielectric(c, eta);
        Vec3<Real> wo;
        if (u_lobe < F) {
            wo = 2 * c * h - w;
            if (!(wo.z > 0)) return out;
            out.reflected = true;
        } else {
            const Real sin2_t = (1 - c * c) / (eta * eta);
            if (!(sin2_t < 1)) return out;
            const Real cos_t = std::sqrt(1 - sin2_t);
            wo = normalize((c / eta - cos_t) * h - (Real(1) / eta) * w);
            if (!(wo.z < 0)) return out;
        }
        if (below) wo.z = -wo.z;
        out.wo = wo;
        out.pdf = pdf(wi, wo);
        if (!(out.pdf > 0)) {
            out.pdf = 0;
            return out;
        }
        out.value = eval(wi, wo);
        return out;
    }

    /// Solid-angle density of sample(wi, ...) at wo: visible-normal density times the selection
    /// probability (F or 1 - F) times the Jacobian dh/dwo (1 / (4 (wo.h)) for reflection,
    /// eta_o^2 |wo.h| / (eta_i (wi.h) + eta_o (wo.h))^2 for refraction). 0 for index matching and smooth (deltas).
    STRATUM_HOST_DEVICE Real pdf(Vec3<Real> wi, Vec3<Real> wo) const noexcept {
        if (!(wi.z != 0) || !(wo.z != 0) || index_matched() || smooth()) return Real(0);
        const bool below = wi.z < 0;
        if (below) {
            wi.z = -wi.z;
            wo.z = -wo.z;
        }
        const Real eta_i = below ? eta_below_ : eta_above_, eta_t = below ? eta_above_ : eta_below_;
        if (wo.z > 0) {
            const Vec3<Real> h = normalize(wi + wo);
            const Real c = dot(wi, h);
            if (!(c > 0) || !(h.z > 0)) return Real(0);
            return distribution_.visible_normal_pdf(wi, h) * fresnel_dielectric(c, eta_t / eta_i) / (4 * c);
        }
        const Vec3<Real> v = eta_i * wi + eta_t * wo;
        const Real len2 = dot(v, v);
        if (!(len2 > 0)) return Real(0);
        Vec3<Real> h = (Real(1) / std::sqrt(len2)) * v;
        if (h.z < 0) h = -h;
        const Real ci = dot(wi, h), co = dot(wo, h);
        if (!(ci > 0) || !(co < 0)) return Real(0);
        const Real T = 1 - fresnel_dielectric(ci, eta_t / eta_i);
        return distribution_.visible_normal_pdf(wi, h) * T * eta_t * eta_t * (-co) / len2;
    }

    /// Hemispherical reflectance and transmittance for light arriving from a direction with cosine mu_i
    /// (mu_i > 0: from above, wi.z = mu_i; mu_i < 0: from below): R = int brdf |wo.z| dwo over wi's
    /// hemisphere, T = int btdf |wo.z| dwo over the other one. Computed over facet slopes, where no Jacobian
    /// appears (so it stays smooth as eta -> 1); see detail::rough_hemispherical_totals for the method. `nodes` is the
    /// Gauss-Legendre count per x panel (3/4 of it per y panel). Accuracy, measured against the previous
    /// implementation at 56 nodes per panel (tests/test_interface_albedo.cpp and a 1944-case grid: sigma in
    /// [1e-4, 2], eta_t / eta_i in {1/2.5, 1/1.4, 1/1.0001, 1 -+ 1e-9, 1.0001, 1.1, 1.4, 2.5}, |mu_i| in [0, 1],
    /// all three Shadowing forms): absolute error <= 1e-8 with the default 16 nodes (largest 9.9e-9, at
    /// sigma = 0.3, eta = 0.4, mu = 0.766, separable; typically < 1e-10), <= 3e-9 with 32 (the reference's own
    /// error). Agreement with the
    /// direct integral of brdf/btdf over wo within that integral's own error (<= 5e-7, test_interface_energy).
    /// Values of `nodes` above 32 are treated as 32. Height-correlated transmission at mu_i = 0 exactly
    /// (Lambda(wi) = inf) is 0, the limit (1 + li)^{-lo} -> 0 for every lo > 0. Smooth interface (smooth()):
    /// exactly {F, 1 - F}, F = fresnel_dielectric(|mu_i|, eta_t / eta_i) (SmoothDielectric's values).
    /// Cost: a two-dimensional integral of 3 000 - 20 000 facet evaluations (more for large sigma and for
    /// eta < 1, where more curves cross): microseconds to a millisecond (BM_interface_hemispherical_totals;
    /// figures in docs/accuracy.md). Throws std::invalid_argument for nodes < 2.
    HemisphericalTotals<Real> hemispherical_totals(Real mu_i, int nodes = 16) const {
        detail::require_count("nodes", nodes, 2);
        nodes = nodes < 32 ? nodes : 32;
        using W = detail::wide_t<Real>;
        if (index_matched()) return {Real(0), Real(1)};
        if (smooth()) {  // the Fresnel values, bit for bit SmoothDielectric's
            const Real F = fresnel_dielectric(std::fmin(std::fabs(mu_i), Real(1)),
                                              mu_i < 0 ? eta_above_ / eta_below_ : eta_below_ / eta_above_);
            return {F, 1 - F};
        }
        const bool below = mu_i < 0;
        const W eta_i = below ? eta_below_ : eta_above_, eta_t = below ? eta_above_ : eta_below_;
        const W m = std::fmin(std::fabs(static_cast<W>(mu_i)), W(1));
        const auto a = detail::rough_hemispherical_totals<W>(distribution_.sigma(), m, eta_t / eta_i, shadowing_, nodes);
        return {static_cast<Real>(a.reflectance), static_cast<Real>(a.transmittance)};
    }

    /// hemispherical_totals(mu_i).reflectance (the same integral: cache the pair where both are needed)
    Real hemispherical_reflectance(Real mu_i) const { return hemispherical_totals(mu_i).reflectance; }
    /// hemispherical_totals(mu_i).transmittance
    Real hemispherical_transmittance(Real mu_i) const { return hemispherical_totals(mu_i).transmittance; }

private:
    // The smooth interface's delta sample for wi (wi.z != 0) and eta = eta_t / eta_i: the mirror direction with
    // probability F (1 under total internal reflection), else the Snell direction (tangential component / eta,
    // normal cosine sqrt(mu^2 + eta^2 - 1) / eta on the other side, as SmoothDielectric::scatter). pdf is the
    // selection probability and value = pdf / |wo.z|, so the weight value |wo.z| / pdf is 1 (BsdfSample).
    STRATUM_HOST_DEVICE static BsdfSample<Real> sample_smooth(Vec3<Real> wi, Real eta, Real u_lobe) noexcept {
        BsdfSample<Real> out;
        out.delta = true;
        const Real mu = std::fmin(std::fabs(wi.z), Real(1));
        const Real F = fresnel_dielectric(mu, eta);
        if (u_lobe < F || !(F < 1)) {
            out.wo = {-wi.x, -wi.y, wi.z};
            out.reflected = true;
            out.pdf = F;
            out.value = F / std::fabs(wi.z);
            return out;
        }
        // F < 1: no total internal reflection, so m2 > 0 (fresnel_dielectric returns 1 for m2 <= 0, eta != 1).
        const Real m2 = mu * mu + (eta - 1) * (eta + 1);
        const Real mt = std::fmin(std::sqrt(m2) / eta, Real(1));
        out.wo = normalize(Vec3<Real>{-wi.x / eta, -wi.y / eta, wi.z > 0 ? -mt : mt});
        out.pdf = 1 - F;
        out.value = out.pdf / std::fabs(out.wo.z);
        return out;
    }

    // G2 / (mu_i mu_o) for cosines mu_i, mu_o (both > 0, already on their own sides), in the wide type: G2
    // vanishes like the cosines at grazing directions, and the quotient stays finite where mu_i mu_o (or its
    // reciprocal) leaves float's range (e.g. 1e-13 * 1e-30); divided one cosine at a time for the same reason.
    STRATUM_HOST_DEVICE detail::wide_t<Real> g2_over_cosines(Real mu_i, Real mu_o, bool transmission) const noexcept {
        using W = detail::wide_t<Real>;
        const W li = distribution_.Lambda(mu_i), lo = distribution_.Lambda(mu_o);
        return detail::smith_g2<W>(li, lo, shadowing_, transmission) / static_cast<W>(mu_i) / static_cast<W>(mu_o);
    }

    Real sigma_;
    Beckmann<Real> distribution_;  // a placeholder of RMS slope smooth_sigma when smooth()
    Real eta_above_;
    Real eta_below_;
    Shadowing shadowing_;
};

/// Result of SmoothDielectric::scatter for one incident direction wi.
template <class Real = double>
struct SpecularScattering {
    Vec3<Real> reflected{};          ///< mirror direction (-wi.x, -wi.y, wi.z), on wi's side
    Vec3<Real> transmitted{};        ///< Snell direction on the other side, pointing away; zero vector under TIR
    Real reflectance = 0;            ///< F: reflected fraction of power (and of radiance)
    Real transmittance = 0;          ///< 1 - F: transmitted fraction of power
    Real radiance_transmittance = 0; ///< (eta_t / eta_i)^2 (1 - F): transmitted radiance per incident radiance
    bool total_internal_reflection = false;
};

/// Smooth dielectric interface: the sigma -> 0 limit of RoughDielectric, as an exact specular interface
/// (no delta is ever evaluated). mu_i is the cosine of wi (towards the light, pointing away from the
/// surface): mu_i > 0 means light arriving from above. Index matching gives F = 0 and identity transmission.
template <class Real = double>
class SmoothDielectric {
public:
    /// eta_above, eta_below: refractive indices in [1e-4, 1e4]; throws std::invalid_argument otherwise.
    SmoothDielectric(Real eta_above, Real eta_below)
        : eta_above_(detail::require_refractive_index("eta_above", eta_above)),
          eta_below_(detail::require_refractive_index("eta_below", eta_below)) {}

    STRATUM_HOST_DEVICE Real eta_above() const noexcept { return eta_above_; }
    STRATUM_HOST_DEVICE Real eta_below() const noexcept { return eta_below_; }

    /// Relative index eta_t / eta_i for light arriving with cosine mu_i.
    STRATUM_HOST_DEVICE Real relative_eta(Real mu_i) const noexcept { return mu_i >= 0 ? eta_below_ / eta_above_ : eta_above_ / eta_below_; }

    /// Fresnel reflectance F(|mu_i|, eta_t / eta_i); 1 under total internal reflection.
    STRATUM_HOST_DEVICE Real reflectance(Real mu_i) const noexcept { return fresnel_dielectric(std::fabs(mu_i), relative_eta(mu_i)); }

    /// Transmitted power fraction 1 - F.
    STRATUM_HOST_DEVICE Real transmittance(Real mu_i) const noexcept { return 1 - reflectance(mu_i); }

    /// Transmitted radiance per incident radiance, (eta_t / eta_i)^2 (1 - F) (radiance / n^2 is invariant).
    STRATUM_HOST_DEVICE Real radiance_transmittance(Real mu_i) const noexcept {
        const Real e = relative_eta(mu_i);
        return e * e * transmittance(mu_i);
    }

    /// Cosine of the transmitted direction (pointing away from the surface, so of the opposite sign to
    /// mu_i): |mu_t| = sqrt(mu_i^2 + eta^2 - 1) / eta, eta = eta_t / eta_i; 0 under total internal reflection.
    STRATUM_HOST_DEVICE Real transmitted_cosine(Real mu_i) const noexcept {
        const Real e = relative_eta(mu_i);
        const Real m2 = mu_i * mu_i + (e - 1) * (e + 1);
        if (!(m2 > 0)) return Real(0);
        const Real mt = std::fmin(std::sqrt(m2) / e, Real(1));
        return mu_i >= 0 ? -mt : mt;
    }

    /// Both scattered directions and their weights for a unit vector wi.
    STRATUM_HOST_DEVICE SpecularScattering<Real> scatter(Vec3<Real> wi) const noexcept {
        SpecularScattering<Real> out;
        out.reflected = {-wi.x, -wi.y, wi.z};
        const Real e = relative_eta(wi.z);
        out.reflectance = reflectance(wi.z);
        out.transmittance = 1 - out.reflectance;
        out.radiance_transmittance = e * e * out.transmittance;
        const Real mt = transmitted_cosine(wi.z);
        if (mt == 0) {
            out.total_internal_reflection = e != Real(1) || wi.z != 0;
            return out;
        }
        // Tangential component scales by 1/eta (Snell), normal component is mt on the other side.
        out.transmitted = {-wi.x / e, -wi.y / e, mt};
        out.transmitted = normalize(out.transmitted);
        return out;
    }

private:
    Real eta_above_;
    Real eta_below_;
};

}  // namespace stratum
