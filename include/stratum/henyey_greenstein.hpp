// stratum/henyey_greenstein.hpp -- the Henyey-Greenstein phase function.
//
// Convention: p is a probability density over the sphere of directions (unit: 1/sr, integral 1),
//   p(cos_theta) = (1 - g^2) / (4 pi (1 + g^2 - 2 g cos_theta)^{3/2}),
// where cos_theta = dot(propagation direction in, propagation direction out). So g > 0 scatters
// forward, g < 0 backward, g = 0 is isotropic (1 / (4 pi)); g is the mean cosine. Note the sign if
// you work with pbrt's wo/wi (both pointing away from the scattering point): there
// cos_theta = -dot(wo, wi). Stam (2001) writes 4 pi p.
//
// Legendre expansion: 4 pi p(x) = sum_l (2l + 1) chi_l P_l(x) with moments chi_l = g^l. Truncation
// after L terms leaves an error of order (2L + 1) |g|^L / (1 - |g|) in 4 pi p.
//
// Azimuthal Fourier coefficients of the discrete-ordinate method (Stam's Appendix C, his 4 pi
// normalization): for mu', mu in [-1, 1] (cosines from the normal) and azimuth difference dphi,
//   4 pi p(cos gamma) = sum_{k>=0} p_k(mu', mu) cos(k dphi),
//   cos gamma = mu' mu + sqrt(1 - mu'^2) sqrt(1 - mu^2) cos(dphi),
//   p_k(mu', mu) = (2 - delta_k0) sum_{n=k}^{N} (2n + 1) chi_n Lambda_n^k(mu') Lambda_n^k(mu),
// with Lambda_n^k the normalized associated Legendre functions of <stratum/legendre.hpp> (so no
// factorial ratio is ever formed). Symmetries: p_k(mu', mu) = p_k(mu, mu') = p_k(-mu', -mu).
// Two routes compute them:
//  * the Legendre series above, for any moments chi_0..chi_N (chi_0 = 1 for a normalized phase
//    function): g^l truncated, or the delta-M scaled moments of delta_m_scaling() --
//    phase_fourier_coefficient(chi, mu', mu, k) and phase_fourier_matrices(chi, mu, modes);
//  * for plain (untruncated) Henyey-Greenstein, a closed form in complete elliptic integrals with a
//    recurrence in k -- HenyeyGreenstein::fourier_coefficients and phase_fourier_matrices(hg, mu, modes).
// Accuracy (double, against mpmath quadrature of the azimuthal integral, coefficients >= 1e-8 p_0):
//   g       series (N = ln(1e-12)/ln g: 263, 2750, 27618 terms)   closed form
//   0.9     rel 8e-8,  abs 6e-15 p_0                              rel 3e-15, abs 7e-16 p_0
//   0.99    rel 6e-5,  abs 7e-13 p_0                              rel 1e-14, abs 8e-15 p_0
//   0.999   rel 3e-3,  abs 5e-11 p_0                              rel 4e-15, abs 3e-15 p_0
// (closed form: up to 1.5e-14 rel / 9.5e-15 p_0 at g = 0.999 and 4.2e-14 rel at g = 0.9999, k = 299, where the
// upward recurrence is taken just below its amplification limit of 64; found by review)
// The series' error is absolute, ~eps (1 + g)/(1 - g)^2 (its terms cancel), so small coefficients
// lose their relative accuracy; the closed form keeps it and costs O(modes) whatever g, while the series
// costs O(N modes) (BM_hg_fourier_pair_series / _closed_form; figures in README and docs/accuracy.md).
// Without delta-M, prefer the closed form; with delta-M (truncated moments) the series is the route.
//
// Also here: sampling by exact CDF inversion (stable for g -> 0 and |g| -> 1), Legendre moments,
// the number of terms for a tolerance, and delta-M scaling (Wiscombe 1977).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <string>
#include <vector>

#include "detail/config.hpp"
#include "detail/elliptic.hpp"
#include "detail/math.hpp"
#include "detail/validate.hpp"
#include "legendre.hpp"
#include "vec3.hpp"

namespace stratum {

/// A sampled scattering direction with its probability density (per steradian).
template <class Real = double>
struct PhaseSample {
    Vec3<Real> direction;  ///< unit vector, the new propagation direction
    Real cos_theta;        ///< cosine between the old and the new propagation direction
    Real pdf;              ///< = eval(cos_theta), 1/sr
};

/// The Henyey-Greenstein phase function with asymmetry parameter g in (-1, 1).
template <class Real = double>
class HenyeyGreenstein {
public:
    /// Throws std::invalid_argument unless -1 < g < 1 (NaN rejected).
    explicit HenyeyGreenstein(Real g) : g_(detail::require_open("g", g, Real(-1), Real(1))) {}

    /// The asymmetry parameter (mean cosine of the scattering angle).
    STRATUM_HOST_DEVICE Real g() const noexcept { return g_; }

    /// The density p(cos_theta) over the sphere, 1/sr; integral over the sphere = 1.
    /// cos_theta = dot(propagation in, propagation out), clamped to [-1, 1].
    STRATUM_HOST_DEVICE Real eval(Real cos_theta) const noexcept {
        const Real c = std::fmin(Real(1), std::fmax(Real(-1), cos_theta));
        return density(Real(1) - c, Real(1) + c);
    }

    /// Samples the scattering angle by exact inversion of the CDF, u1 in [0, 1), and the azimuth
    /// phi = 2 pi u2 around +z: direction = (sin cos phi, sin sin phi, cos_theta), i.e. the frame
    /// whose z axis is the incoming propagation direction. pdf = eval(cos_theta), exactly (at the cos_theta returned:
    /// where it rounds to +-1, as for g within a few eps^(1/2) of 1 in float, that is the density there).
    /// With d = 1 + g (2 u1 - 1) the inverse CDF is, in product form (no cancellation anywhere,
    /// stable for g -> 0 and |g| -> 1):
    ///   1 - cos_theta = 2 (1 - g)^2 (1 - u1) (1 + g u1) / d^2,
    ///   1 + cos_theta = 2 (1 + g)^2 u1 (1 - g (1 - u1)) / d^2,
    /// with d, 1 + g u1 and 1 - g (1 - u1) each formed as sums of non-negative terms
    /// (e.g. 1 - g (1 - u1) = (1 - g) + g u1 for g > 0); equivalent to the textbook cos = (1 + g^2 - ((1 - g^2) / d)^2) / (2g), which cancels as g -> 0.
    STRATUM_HOST_DEVICE PhaseSample<Real> sample(Real u1, Real u2) const noexcept {
        const Real u = std::fmin(std::fmax(u1, Real(0)), Real(1));
        const Real one_minus_u = Real(1) - u;
        const Real d = g_ >= 0 ? (Real(1) - g_) + Real(2) * g_ * u : (Real(1) + g_) - Real(2) * g_ * one_minus_u;
        const Real inv_d2 = Real(1) / (d * d);
        const Real omg = Real(1) - g_, opg = Real(1) + g_;
        // 1 + g u and 1 - g (1 - u), each formed as a sum of non-negative terms for either sign of g.
        const Real a = g_ >= 0 ? Real(1) + g_ * u : opg - g_ * one_minus_u;
        const Real b = g_ >= 0 ? omg + g_ * u : Real(1) - g_ * one_minus_u;
        const Real one_minus_c = Real(2) * omg * omg * one_minus_u * a * inv_d2;
        const Real one_plus_c = Real(2) * opg * opg * u * b * inv_d2;
        // cos_theta from the smaller of 1 -+ c (one rounding), and the pdf eval(cos_theta) at it, so that a renderer's
        // eval at the direction returned agrees with the pdf reported: from the unrounded 1 - c it was 57% off in float
        // at g = 0.999 and 1e8 times at g = 0.999999, where cos_theta rounds to 1 (found by a review sweep).
        const Real c = std::fmin(Real(1), std::fmax(Real(-1), one_minus_c <= one_plus_c ? Real(1) - one_minus_c : one_plus_c - Real(1)));
        const Real sin_theta = std::sqrt(std::fmax(Real(0), one_minus_c * one_plus_c));
        const Real phi = detail::two_pi_v<Real> * detail::clamp_uniform(u2);  // (a NaN u2 gave a NaN direction)
        return {{sin_theta * std::cos(phi), sin_theta * std::sin(phi), c}, c, eval(c)};
    }

    /// As sample(u1, u2), around the unit vector `axis` (the incoming propagation direction):
    /// dot(axis, direction) = cos_theta. The frame is the branchless one of Duff et al. (2017).
    STRATUM_HOST_DEVICE PhaseSample<Real> sample(const Vec3<Real>& axis, Real u1, Real u2) const noexcept {
        PhaseSample<Real> local = sample(u1, u2);
        const Real sign = std::copysign(Real(1), axis.z);
        const Real a = Real(-1) / (sign + axis.z);
        const Real b = axis.x * axis.y * a;
        const Vec3<Real> t{Real(1) + sign * axis.x * axis.x * a, sign * b, -sign * axis.x};
        const Vec3<Real> bt{b, sign + axis.y * axis.y * a, -axis.y};
        local.direction = local.direction.x * t + local.direction.y * bt + local.direction.z * axis;
        return local;
    }

    /// The Legendre moments chi_l = g^l, l = 0..count-1. Throws std::invalid_argument if count < 1.
    std::vector<Real> legendre_moments(int count) const {
        detail::require_count("count", count, 1);
        std::vector<Real> chi(static_cast<std::size_t>(count));
        Real gl = 1;
        for (auto& c : chi) {
            c = gl;
            gl *= g_;
        }
        return chi;
    }

    /// The number of moments L (l = 0..L-1) for which the first neglected moment |g|^L <= tolerance:
    /// L = ceil(ln(tolerance) / ln|g|), at least 1 (1 for g = 0). E.g. 263 at g = 0.9 and
    /// tolerance 1e-12, 2750 at g = 0.99. At most 1e8 (returned where more would be needed: g within
    /// ~1e-8 of +-1 at tolerance 1e-12, where |g|^L is then above the tolerance). The truncation error of 4 pi p is about
    /// (2L + 1) |g|^L / (1 - |g|): ask for a tolerance a few digits below the accuracy you need.
    /// Throws std::invalid_argument unless 0 < tolerance < 1.
    int legendre_terms_for_tolerance(Real tolerance) const {
        detail::require_open("tolerance", tolerance, Real(0), Real(1));
        const Real ag = std::fabs(g_);
        if (ag == 0) return 1;
        const Real terms = std::ceil(std::log(tolerance) / std::log(ag));
        return terms < Real(1) ? 1 : terms > Real(1e8) ? 100000000 : static_cast<int>(terms);
    }

    /// The azimuthal Fourier coefficients p_0..p_{modes-1}(mu', mu) of this phase function, untruncated
    /// (the limit N -> inf of the Legendre series; 4 pi normalization), in closed form, written to
    /// out[0..modes-1]. O(modes) work (plus the Miller start-up below) whatever g, where the
    /// Legendre series needs ~ln(eps)/ln|g| terms (36026 at g = 0.999; 27618 for 1e-12). mu', mu in [-1, 1] (clamped).
    ///
    /// With D = 1 + g^2 - 2 g mu' mu and E = 2 g sin(theta') sin(theta) (g >= 0; g < 0 maps to -g by
    /// p_k^g(mu', mu) = (-1)^k p_k^{-g}(-mu', mu)), 4 pi p = (1 - g^2) (D - E cos phi)^{-3/2} and
    ///   p_k = (2 - delta_k0) (1 - g^2) / pi * E^{-3/2} J_k(z),  J_k(z) = int_0^pi cos(k phi) (z - cos phi)^{-3/2} dphi,
    /// z = D / E > 1. Closed forms (Gradshteyn-Ryzhik 3.674; m^2 = 2 / (z + 1), K, E complete elliptic):
    ///   p_0 = (1 - g^2) / pi * 2 E(m) / ((D - E) sqrt(D + E)),   J_1 / J_0 = 1 - (z - 1) (K(m) - E(m)) / E(m),
    /// and integration by parts gives (k - 1/2) J_{k+1} = 2 k z J_k - (k + 1/2) J_{k-1}.
    /// J_k is the recurrence's minimal solution (~ rho^-k, rho = z + sqrt(z^2 - 1)): running it upwards
    /// amplifies rounding by ~rho^{2k}. So: upwards from the closed forms while rho^{2(modes-1)} <= 64
    /// (the peaked case, z near 1); otherwise Miller's algorithm (in ratio form), downwards from
    /// k = modes - 1 + ln(1/eps) / (2 ln rho) and normalized by the closed-form J_0. Both run on
    /// differences (r_k - r_{k-1}), which keeps them accurate near the double root z = 1.
    /// D - E = (1 - g)^2 + 4 g sin^2((theta' - theta)/2) and D + E are formed without cancellation, so
    /// the peak (mu' = mu, g -> 1) keeps full relative accuracy. E = 0 (a pole, or g = 0) gives
    /// p_0 = (1 - g^2) / D^{3/2} and p_k = 0.
    void fourier_coefficients(Real mu_prime, Real mu, int modes, Real* out) const noexcept {
        if (modes <= 0) return;
        Real a = std::fmin(Real(1), std::fmax(Real(-1), mu_prime));
        const Real b = std::fmin(Real(1), std::fmax(Real(-1), mu));
        const bool flip = g_ < 0;
        const Real g = std::fabs(g_);
        if (flip) a = -a;
        const Real sa = std::sqrt((Real(1) - a) * (Real(1) + a)), sb = std::sqrt((Real(1) - b) * (Real(1) + b));
        const Real E = Real(2) * g * sa * sb;
        // 1 - cos(theta_a -+ theta_b) = ((a - b)^2 + (sa -+ sb)^2) / 2, sa - sb = (b - a)(b + a) / (sa + sb).
        const Real dmu = a - b;
        const Real dsin = sa + sb > 0 ? (b - a) * (b + a) / (sa + sb) : Real(0);
        const Real one_minus_cos_diff = (dmu * dmu + dsin * dsin) / Real(2);
        const Real one_minus_cos_sum = (dmu * dmu + (sa + sb) * (sa + sb)) / Real(2);
        const Real omg = Real(1) - g;
        const Real d_minus = omg * omg + Real(2) * g * one_minus_cos_diff;  // D - E > 0
        const Real d_plus = omg * omg + Real(2) * g * one_minus_cos_sum;    // D + E
        const Real pref = (Real(1) - g) * (Real(1) + g);
        for (int k = 1; k < modes; ++k) out[k] = Real(0);
        if (!(E > 0)) {
            out[0] = pref / (d_minus * std::sqrt(d_minus));
            return;
        }
        const auto ell = detail::complete_elliptic(Real(2) * E / d_plus, d_minus / d_plus);  // m^2, 1 - m^2
        const Real p0 = pref * detail::inv_pi_v<Real> * Real(2) * ell.E / (d_minus * std::sqrt(d_plus));
        out[0] = p0;
        if (modes == 1) return;
        const Real zm1 = d_minus / E, zp1 = d_plus / E;  // z - 1, z + 1
        const Real log_rho = std::log1p(zm1 + std::sqrt(zm1 * zp1));  // acosh(z)
        if (Real(2) * static_cast<Real>(modes - 1) * log_rho <= std::log(Real(64))) {
            // Upwards: out[k] holds r_k = J_k / J_0 for now. Near z = 1 the recurrence has a double
            // characteristic root (rho -> 1) and the plain form loses ~k^2 ulp; carrying the
            // difference d_k = r_k - r_{k-1} (as the Legendre stepper does near its poles) with
            // w = z - 1 exact in relative terms:
            //   d_{k+1} = (2 k w r_k + (k + 1/2) d_k) / (k - 1/2),   r_{k+1} = r_k + d_{k+1},
            //   d_1 = -w (K - E) / E.
            Real r = 1, d = -zm1 * ell.K_minus_E / ell.E;
            r += d;
            out[1] = r;
            for (int k = 1; k + 1 < modes; ++k) {
                const Real kr = static_cast<Real>(k);
                d = (Real(2) * kr * zm1 * r + (kr + Real(0.5)) * d) / (kr - Real(0.5));
                r += d;
                out[k + 1] = r;
            }
        } else {
            // Miller's algorithm in ratio form: downwards from k_start (s_{k_start + 1} = 0), with
            // t_k = (s_{k-1} - s_k) / s_k >= 0 for the minimal solution s (positive, decreasing):
            //   t_k = (2 k w + (k - 1/2) t_{k+1} / (1 + t_{k+1})) / (k + 1/2),  t_{k_start+1}/(1 + .) = 1,
            // then r_k = r_{k-1} / (1 + t_k). Every term is non-negative (no cancellation, even near
            // the double root z -> 1) and nothing can overflow, however large z is.
            const Real extra = std::ceil(-std::log(std::numeric_limits<Real>::epsilon()) / (Real(2) * log_rho));
            const int k_start = modes - 1 + 2 + (extra > Real(1e7) ? 10000000 : static_cast<int>(extra));
            Real ratio = 1;  // t_{k+1} / (1 + t_{k+1})
            for (int k = k_start; k >= 1; --k) {
                const Real kr = static_cast<Real>(k);
                const Real t = (Real(2) * kr * zm1 + (kr - Real(0.5)) * ratio) / (kr + Real(0.5));
                // (t = inf where z - 1 = (D - E) / E overflows, tiny g E: then s_k / s_{k-1} = 0, and t / (1 + t)
                // would be NaN; found by review, g = 1e-300 at mu' = mu = 1 - ulp)
                ratio = std::isinf(t) ? Real(1) : t / (Real(1) + t);
                if (k < modes) out[k] = t;
            }
            Real r = 1;
            for (int k = 1; k < modes; ++k) {
                r /= Real(1) + out[k];
                out[k] = r;
            }
        }
        out[0] = p0;
        for (int k = 1; k < modes; ++k) out[k] *= Real(2) * p0 * (flip && k % 2 == 1 ? Real(-1) : Real(1));
    }

private:
    /// p from 1 - c and 1 + c; the denominator 1 + g^2 - 2 g c is formed as (1 - g)^2 + 2 g (1 - c)
    /// for g >= 0 and as (1 + g)^2 - 2 g (1 + c) for g < 0: sums of non-negative terms, so the peak
    /// value keeps full relative accuracy as |g| -> 1 (the direct form cancels).
    STRATUM_HOST_DEVICE Real density(Real one_minus_c, Real one_plus_c) const noexcept {
        const Real omg = Real(1) - g_, opg = Real(1) + g_;
        const Real denom = g_ >= 0 ? omg * omg + Real(2) * g_ * one_minus_c : opg * opg - Real(2) * g_ * one_plus_c;
        return omg * opg * detail::inv_four_pi_v<Real> / (denom * std::sqrt(denom));
    }
    Real g_;
};

/// The azimuthal Fourier coefficient p_k(mu', mu) (4 pi normalization, see the top of this file) of
/// the phase function with Legendre moments chi[0..N], at arbitrary mu', mu in [-1, 1] (clamped).
/// Allocation-free, O(N) work (two normalized-Legendre recurrences in lockstep). k < 0 or k > N gives 0.
template <class Real>
Real phase_fourier_coefficient(const std::vector<Real>& chi, Real mu_prime, Real mu, int k) noexcept {
    const int N = static_cast<int>(chi.size()) - 1;
    if (k < 0 || k > N) return Real(0);
    mu_prime = std::fmin(Real(1), std::fmax(Real(-1), mu_prime));
    mu = std::fmin(Real(1), std::fmax(Real(-1), mu));
    detail::LambdaStepper<Real> a(k, mu_prime), b(k, mu);
    Real sum = 0;
    for (int n = k;; ++n) {
        sum += (a.value() * b.value()) * (static_cast<Real>(2 * n + 1) * chi[static_cast<std::size_t>(n)]);
        if (n == N) break;
        const auto c = detail::LambdaCoefficients<Real>::at(n + 1, k);
        a.step(c);
        b.step(c);
    }
    return k == 0 ? sum : Real(2) * sum;
}

/// The Fourier-mode matrices of the phase function on a set of ordinates, for the discrete-ordinate
/// layer solver: for modes k = 0..modes-1 and ordinates mu_0..mu_{M-1} in (0, 1],
///   same_k(k)[n * M + m]     = p_k( mu_m, mu_n)   (row n, column m, row-major),
///   opposite_k(k)[n * M + m] = p_k(-mu_m, mu_n),
/// with p_k as above (4 pi normalization). Both are symmetric in (n, m).
template <class Real = double>
struct PhaseFourierMatrices {
    int modes = 0;  ///< K
    int size = 0;   ///< M
    std::vector<Real> same, opposite;  ///< each K * M * M, index (k * M + n) * M + m
    const Real* same_k(int k) const noexcept { return same.data() + static_cast<std::size_t>(k) * block(); }
    const Real* opposite_k(int k) const noexcept { return opposite.data() + static_cast<std::size_t>(k) * block(); }

private:
    std::size_t block() const noexcept { return static_cast<std::size_t>(size) * static_cast<std::size_t>(size); }
};

namespace detail {

/// Appends modes out.modes .. modes - 1 (modes >= out.modes) to `out`, whose `size` is mu.size(), by the method of
/// phase_fourier_matrices below (which validates the arguments): a solver that stops at a tolerance computes the
/// matrices of the modes it solves only. Modes k > N are zero.
template <class Real>
void append_phase_fourier_modes(const std::vector<Real>& chi, const std::vector<Real>& mu, int modes,
                                PhaseFourierMatrices<Real>& out) {
    const int N = static_cast<int>(chi.size()) - 1, first = out.modes;
    const auto Ms = mu.size();
    out.modes = modes;
    out.same.resize(static_cast<std::size_t>(modes) * Ms * Ms, Real(0));
    out.opposite.resize(out.same.size(), Real(0));

    std::vector<detail::LambdaCoefficients<Real>> coef(static_cast<std::size_t>(N) + 1);
    // table[j * M + m] = Lambda_{k+j}^k(mu_m): degree-major, so that the inner loop below runs over
    // contiguous ordinates (independent lanes the compiler vectorizes; a dot product over degrees
    // would be one long dependency chain).
    std::vector<Real> table, weight, even(Ms), odd(Ms);
    std::vector<detail::SectoralSeed<Real>> seeds;  // per ordinate, advanced one order per mode
    seeds.reserve(Ms);
    for (std::size_t m = 0; m < Ms; ++m) {
        seeds.emplace_back(mu[m]);
        for (int k = 0; k < first && k < N; ++k) seeds.back().next();  // to order first (O(first) steps)
    }
    std::vector<detail::LambdaStepper<Real>> steppers;
    steppers.reserve(Ms);
    for (int k = first; k < modes && k <= N; ++k) {
        if (k > first)
            for (auto& seed : seeds) seed.next();
        const auto count = static_cast<std::size_t>(N - k + 1);
        for (int n = k + 1; n <= N; ++n) coef[static_cast<std::size_t>(n)] = detail::LambdaCoefficients<Real>::at(n, k);
        table.assign(count * Ms, Real(0));
        weight.assign(count, Real(0));
        const Real two = k == 0 ? Real(1) : Real(2);
        for (std::size_t j = 0; j < count; ++j)
            weight[j] = two * static_cast<Real>(2 * (static_cast<std::size_t>(k) + j) + 1) * chi[static_cast<std::size_t>(k) + j];
        // All ordinates advance together: M independent recurrences per degree overlap in the
        // pipeline (one ordinate at a time is a latency-bound chain).
        steppers.clear();
        for (std::size_t m = 0; m < Ms; ++m) {
            steppers.emplace_back(seeds[m], mu[m]);
            table[m] = steppers[m].value();
        }
        for (std::size_t j = 1; j < count; ++j) {
            const auto& c = coef[static_cast<std::size_t>(k) + j];
            for (std::size_t m = 0; m < Ms; ++m) {
                steppers[m].step(c);
                table[j * Ms + m] = steppers[m].value();
            }
        }
        Real* same = out.same.data() + static_cast<std::size_t>(k) * Ms * Ms;
        Real* opposite = out.opposite.data() + static_cast<std::size_t>(k) * Ms * Ms;
        for (std::size_t n = 0; n < Ms; ++n) {
            // Row n, columns m <= n; even / odd: degrees with n + k even / odd (j even / odd).
            std::fill(even.begin(), even.begin() + static_cast<std::ptrdiff_t>(n + 1), Real(0));
            std::fill(odd.begin(), odd.begin() + static_cast<std::ptrdiff_t>(n + 1), Real(0));
            for (std::size_t parity = 0; parity < 2; ++parity) {
                Real* acc = parity == 0 ? even.data() : odd.data();
                std::size_t j = parity;
                for (; j + 6 < count; j += 8) {  // four degrees of one parity per pass over the row
                    const Real *t0 = table.data() + j * Ms, *t1 = t0 + 2 * Ms, *t2 = t1 + 2 * Ms, *t3 = t2 + 2 * Ms;
                    const Real c0 = weight[j] * t0[n], c1 = weight[j + 2] * t1[n];
                    const Real c2 = weight[j + 4] * t2[n], c3 = weight[j + 6] * t3[n];
                    for (std::size_t m = 0; m <= n; ++m) acc[m] += (c0 * t0[m] + c1 * t1[m]) + (c2 * t2[m] + c3 * t3[m]);
                }
                for (; j < count; j += 2) {
                    const Real* t = table.data() + j * Ms;
                    const Real c = weight[j] * t[n];
                    for (std::size_t m = 0; m <= n; ++m) acc[m] += c * t[m];
                }
            }
            for (std::size_t m = 0; m <= n; ++m) {
                same[n * Ms + m] = same[m * Ms + n] = even[m] + odd[m];
                opposite[n * Ms + m] = opposite[m * Ms + n] = even[m] - odd[m];
            }
        }
    }
}

}  // namespace detail

/// Computes PhaseFourierMatrices for the moments chi[0..N] (chi_0 = 1 for a normalized phase function),
/// the ordinates mu (each in (0, 1]) and `modes` >= 1 Fourier modes. Modes k > N are zero.
/// Method: per k, the values Lambda_n^k(mu_m) (n = k..N) are tabulated once per ordinate, split by the
/// parity of n + k, so that with E = sum over n + k even and O = sum over n + k odd of
/// (2 - delta_k0)(2n + 1) chi_n Lambda_n^k(mu_m) Lambda_n^k(mu_n'):
///   p_k(mu_m, mu_n) = E + O,  p_k(-mu_m, mu_n) = E - O   (parity Lambda_n^k(-x) = (-1)^{n+k} Lambda_n^k(x)).
/// Cost ~ K (M N recurrence steps + M^2 N / 2 multiply-adds). Throws std::invalid_argument for empty or non-finite chi,
/// an ordinate outside (0, 1], or modes < 1.
template <class Real>
PhaseFourierMatrices<Real> phase_fourier_matrices(const std::vector<Real>& chi, const std::vector<Real>& mu,
                                                   int modes) {
    detail::require_count("modes", modes, 1);
    detail::require_count("chi.size()", static_cast<int>(chi.size()), 1);
    detail::require_count("mu.size()", static_cast<int>(mu.size()), 1);
    for (std::size_t l = 0; l < chi.size(); ++l)
        if (!std::isfinite(chi[l]))
            detail::throw_out_of_range(("chi[" + std::to_string(l) + "]").c_str(), chi[l], "(-inf, inf)");
    for (std::size_t m = 0; m < mu.size(); ++m)
        if (!(mu[m] > 0 && mu[m] <= 1))
            detail::throw_out_of_range(("mu[" + std::to_string(m) + "]").c_str(), mu[m], "(0, 1]");

    PhaseFourierMatrices<Real> out;
    out.size = static_cast<int>(mu.size());
    detail::append_phase_fourier_modes(chi, mu, modes, out);
    return out;
}

/// PhaseFourierMatrices of the untruncated Henyey-Greenstein phase function, by the closed form of
/// HenyeyGreenstein::fourier_coefficients (elliptic integrals + recurrence in k) for each pair of
/// ordinates: cost ~ M^2 (modes + a few hundred) whatever g, against ~ K M^2 N / 2 for the Legendre
/// series, whose length N ~ ln(eps)/ln|g| grows without bound as |g| -> 1. Use this overload for plain
/// HG; use the moments overload for delta-M scaled (or any other) phase functions.
/// Throws std::invalid_argument for an ordinate outside (0, 1] or modes < 1.
template <class Real>
PhaseFourierMatrices<Real> phase_fourier_matrices(const HenyeyGreenstein<Real>& hg, const std::vector<Real>& mu,
                                                   int modes) {
    detail::require_count("modes", modes, 1);
    detail::require_count("mu.size()", static_cast<int>(mu.size()), 1);
    for (std::size_t m = 0; m < mu.size(); ++m)
        if (!(mu[m] > 0 && mu[m] <= 1))
            detail::throw_out_of_range(("mu[" + std::to_string(m) + "]").c_str(), mu[m], "(0, 1]");
    const std::size_t Ms = mu.size(), K = static_cast<std::size_t>(modes);
    PhaseFourierMatrices<Real> out;
    out.modes = modes;
    out.size = static_cast<int>(Ms);
    out.same.assign(K * Ms * Ms, Real(0));
    out.opposite.assign(out.same.size(), Real(0));
    std::vector<Real> same(K), opposite(K);
    for (std::size_t n = 0; n < Ms; ++n)
        for (std::size_t m = 0; m <= n; ++m) {
            hg.fourier_coefficients(mu[m], mu[n], modes, same.data());
            hg.fourier_coefficients(-mu[m], mu[n], modes, opposite.data());
            for (std::size_t k = 0; k < K; ++k) {
                const std::size_t base = k * Ms * Ms;
                out.same[base + n * Ms + m] = out.same[base + m * Ms + n] = same[k];
                out.opposite[base + n * Ms + m] = out.opposite[base + m * Ms + n] = opposite[k];
            }
        }
    return out;
}

/// Delta-M scaled layer parameters (Wiscombe 1977) for a Henyey-Greenstein medium.
template <class Real = double>
struct DeltaMScaled {
    Real albedo;             ///< Omega' = (1 - f) Omega / (1 - f Omega)
    Real optical_thickness;  ///< tau' = (1 - f Omega) tau
    std::vector<Real> moments;  ///< chi'_l = (g^l - f) / (1 - f), l = 0..L-1 (chi'_0 = 1)
    Real f;                  ///< the truncated forward-peak fraction, f = g^L
};

/// Delta-M scaling of a Henyey-Greenstein layer keeping L = `moments` Legendre moments (l = 0..L-1):
/// the forward peak f = g^L is moved into the unscattered beam, leaving a phase function whose
/// truncated expansion with moments chi'_l is exact in its first L moments. Use the scaled albedo,
/// optical thickness and moments with phase_fourier_matrices in place of the originals.
/// (For g < 0 and odd L, f < 0; choose L even as Wiscombe does with 2M streams.)
/// Throws std::invalid_argument unless 0 <= albedo <= 1, optical_thickness >= 0 (inf allowed),
/// -1 < g < 1 and moments >= 1.
template <class Real>
DeltaMScaled<Real> delta_m_scaling(Real albedo, Real optical_thickness, Real g, int moments) {
    detail::require_closed("albedo", albedo, Real(0), Real(1));
    if (!(optical_thickness >= 0)) detail::throw_out_of_range("optical_thickness", optical_thickness, "[0, inf]");
    const HenyeyGreenstein<Real> hg(g);
    detail::require_count("moments", moments, 1);
    DeltaMScaled<Real> out;
    out.f = std::pow(g, static_cast<Real>(moments));
    const Real f = out.f;
    out.moments = hg.legendre_moments(moments);
    for (auto& chi : out.moments) chi = (chi - f) / (Real(1) - f);
    out.moments[0] = Real(1);
    const Real one_minus_f_omega = Real(1) - f * albedo;
    out.albedo = (Real(1) - f) * albedo / one_minus_f_omega;
    out.optical_thickness = one_minus_f_omega * optical_thickness;
    return out;
}

}  // namespace stratum
