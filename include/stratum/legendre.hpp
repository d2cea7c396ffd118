// stratum/legendre.hpp -- Legendre polynomials and normalized associated Legendre functions.
//
// P_l(x): the Legendre polynomials, P_0 = 1, P_1 = x, l P_l = (2l - 1) x P_{l-1} - (l - 1) P_{l-2}.
//
// Lambda_l^k(x) = sqrt((l - k)! / (l + k)!) P_l^k(x), 0 <= k <= l, x = cos(theta) in [-1, 1], with the
// Condon-Shortley sign: P_l^k(x) = (-1)^k (1 - x^2)^{k/2} d^k P_l / dx^k, so Lambda_1^1 = -sin(theta)/sqrt(2).
// (The product Lambda_l^k(x') Lambda_l^k(x) that the phase-function expansions use does not depend on
// the sign convention.) Properties used by the tests:
//   addition theorem   sum_{k=0}^{l} (2 - delta_k0) Lambda_l^k(x)^2 = 1, hence |Lambda_l^k| <= 1;
//   orthogonality      int_{-1}^{1} Lambda_l^k Lambda_n^k dx = 2 / (2l + 1) delta_ln;
//   parity             Lambda_l^k(-x) = (-1)^{l+k} Lambda_l^k(x).
//
// Numerics. The recurrence in l at fixed k,
//   Lambda_k^k     = (-1)^k c_k sin^k(theta),   c_k = prod_{i=1}^{k} sqrt((2i - 1) / (2i)),
//   Lambda_{k+1}^k = sqrt(2k + 1) x Lambda_k^k,
//   sqrt(l^2 - k^2) Lambda_l^k = (2l - 1) x Lambda_{l-1}^k - sqrt((l - 1)^2 - k^2) Lambda_{l-2}^k,
// never forms the factorials (which overflow double beyond l + k ~ 170) and is stable upwards in l.
// Its seed sin^k(theta) underflows near the poles (0.024^200 ~ 1e-324 at the outermost node of a
// 100-point Gauss rule) although Lambda_l^k for larger l is representable there (~1e-99 at l = 2000).
// The recurrence therefore runs on a mantissa with a separate binary exponent ("extended exponent",
// as in geodesy codes): value = a * 2^E. The seed is built factor by factor (in long double for
// double) with exact power-of-two rescaling; when |a| outgrows 2^T during the recurrence both carried
// terms are scaled by 2^-T (exact, the recurrence is linear). Each output is a * 2^E rounded once, so
// a value below the smallest subnormal is 0, never NaN, and every representable value is delivered for |x| above
// ~1e-230 (below, the mantissa's product with x underflows before the exponent applies: Lambda_1001^1000 at x = 1e-300
// is returned as 0 for 5.97e-300, 1.5e-5 off at 1e-250; found by review; the solver's cosines are far above).
// For |x| >= 1/2 the recurrence carries Lambda_l - Lambda_{l-1} (Reinsch's modification), which
// removes the linear error growth of the plain recurrence near the poles.
// Measured against exact-arithmetic references (tests/data/gen_legendre.py; l <= 2000, k <= 2000,
// x up to 1 - 2^-40): worst relative error 3.1e-14 in double, 5.2e-6 in float; the addition theorem
// holds to 1.8e-14 at l = 2000. Recurrence coefficients are computed on the fly (BM_legendre_lambda_all).
// x = +-1 exactly gives the limits (Lambda_l^0 = (+-1)^l, Lambda_l^k = 0 for k > 0).
//
// API: legendre_p(l, x), legendre_p_all(lmax, x, out), legendre_lambda(l, k, x),
// legendre_lambda_all(k, lmax, x, out) -- all noexcept and allocation-free.
#pragma once

#include <cmath>
#include <limits>

namespace stratum {

namespace detail {

/// The type in which the seed product is formed: one step wider than Real where the platform has it.
template <class Real>
struct Wider {
    using type = long double;
};
template <>
struct Wider<float> {
    using type = double;
};

/// Recurrence coefficients at degree l >= k + 1 for fixed order k, with r_l = sqrt((l - k)(l + k))
/// (r_k = 0; the integers are exact in Real):
///   Lambda_l = alpha_l x Lambda_{l-1} - beta_l Lambda_{l-2},  alpha_l = (2l - 1) / r_l,  beta_l = r_{l-1} / r_l,
///   gamma_l = alpha_l - beta_l - 1 = [k^2 / (l + r_l) + k^2 / (l - 1 + r_{l-1})] / r_l  (>= 0, no cancellation).
/// gamma drives the difference form used near the poles (see LambdaStepper).
template <class Real>
struct LambdaCoefficients {
    Real alpha, beta, gamma;
    static LambdaCoefficients at(int l, int k) noexcept {
        const Real r = std::sqrt(static_cast<Real>(l - k) * static_cast<Real>(l + k));
        const Real r1 = std::sqrt(static_cast<Real>(l - 1 - k) * static_cast<Real>(l - 1 + k));
        const Real k2 = static_cast<Real>(k) * static_cast<Real>(k);
        const Real gamma = k == 0 ? Real(0)
                                  : (k2 / (static_cast<Real>(l) + r) + k2 / (static_cast<Real>(l - 1) + r1)) / r;
        return {static_cast<Real>(2 * l - 1) / r, r1 / r, gamma};
    }
};

/// Exponent step T of the extended-exponent arithmetic: 2^T and 2^-T are exact normal numbers and
/// a mantissa <= 2^T times a recurrence coefficient (<= 2 sqrt(l)) cannot overflow. 256 for double.
template <class Real>
constexpr int lambda_exponent_step() noexcept {
    return std::numeric_limits<Real>::max_exponent / 4;
}

/// The sectoral values |Lambda_k^k(x)| = c_k sin^k(theta), c_k = prod_{i<=k} sqrt((2i - 1) / (2i)), as
/// mantissa * 2^exponent, advanced one order at a time (so a caller needing every k pays O(1) per k).
/// sin(theta) and the products are formed in a wider type (long double for double): in Real, the
/// rounding of sin(theta) alone costs up to k/2 ulp (2e-13 at k = 2000) and the product another ~k/4.
/// Each factor lies in [0.35, 1) (sin = ms 2^es, ms in [1/2, 1)), so rescaling by 2^T whenever the
/// mantissa drops below 2^-T keeps it normal. Not part of the API.
template <class Real>
class SectoralSeed {
public:
    using W = typename Wider<Real>::type;

    explicit SectoralSeed(Real x) noexcept {
        const W y = std::fabs(static_cast<W>(x));
        const W s = std::sqrt(std::fmax(W(0), (W(1) - y) * (W(1) + y)));  // exact products in W
        pole_ = !(s > 0);
        ms_ = pole_ ? W(0) : std::frexp(s, &es_);
    }
    /// k -> k + 1.
    void next() noexcept {
        ++k_;
        mantissa_ *= ms_ * std::sqrt(static_cast<W>(2 * k_ - 1) / static_cast<W>(2 * k_));
        exponent_ += es_;
        if (mantissa_ < down() && mantissa_ > 0) {
            mantissa_ *= up();
            exponent_ -= lambda_exponent_step<Real>();
        }
    }
    int order() const noexcept { return k_; }
    W mantissa() const noexcept { return k_ > 0 && pole_ ? W(0) : mantissa_; }
    long exponent() const noexcept { return exponent_; }

private:
    static W up() noexcept { return std::ldexp(W(1), lambda_exponent_step<Real>()); }
    static W down() noexcept { return std::ldexp(W(1), -lambda_exponent_step<Real>()); }
    int k_ = 0, es_ = 0;
    bool pole_ = false;
    W ms_ = 0, mantissa_ = 1;
    long exponent_ = 0;
};

/// The upward recurrence for Lambda_l^k(x) at fixed k, one degree per step, on an extended exponent.
/// Construction gives l = k; step() moves to l + 1. Several steppers can run in lockstep (products
/// Lambda(x') Lambda(x) without storage). Not part of the API.
///
/// It runs at y = |x| and restores the sign by parity, (-1)^{l+k} for x < 0 (so parity is exact).
/// For y >= 1/2 it carries the difference d_l = Lambda_l - Lambda_{l-1} instead of Lambda_{l-2}
/// (Reinsch's modification, as for Clenshaw's sum near x = 1): with u = 1 - y (exact there),
///   d_l = beta_l d_{l-1} + (gamma_l - alpha_l u) Lambda_{l-1},   Lambda_l = Lambda_{l-1} + d_l.
/// Near the pole the plain recurrence has a double characteristic root at 1 and amplifies rounding
/// linearly in l (measured: 3e3 ulp at l = 2000, x = 1 - 2^-40); the difference form does not.
template <class Real>
class LambdaStepper {
public:
    static constexpr int T = lambda_exponent_step<Real>();

    /// Starts at l = k (O(k) work for the seed).
    LambdaStepper(int k, Real x) noexcept : LambdaStepper(advance(SectoralSeed<Real>(x), k), x) {}

    /// Starts at l = seed.order() from a seed advanced to that order at the same x (O(1)).
    LambdaStepper(const SectoralSeed<Real>& seed, Real x) noexcept
        : k_(seed.order()), l_(seed.order()), y_(std::fabs(x)), u_(Real(1) - std::fabs(x)), negative_(x < 0),
          difference_(std::fabs(x) >= Real(0.5)) {
        cur_ = static_cast<Real>(seed.mantissa());  // Condon-Shortley sign (-1)^k
        if (k_ % 2 == 1) cur_ = -cur_;
        E_ = cur_ == 0 ? 0 : seed.exponent();
        other_ = difference_ ? cur_ : Real(0);  // d_k = Lambda_k - 0, or Lambda_{k-1} = 0
        refresh();
    }

    int degree() const noexcept { return l_; }

    /// Lambda_l^k(x) rounded once to Real (0 below the smallest subnormal).
    Real value() const noexcept {
        const Real v = normal_ ? cur_ * factor_ : std::ldexp(cur_, static_cast<int>(E_ < -100000 ? -100000 : E_));
        return negative_ && (l_ + k_) % 2 == 1 ? -v : v;
    }

    /// l -> l + 1 with the given coefficients (LambdaCoefficients<Real>::at(l + 1, k)).
    void step(const LambdaCoefficients<Real>& c) noexcept {
        if (difference_) {
            other_ = c.beta * other_ + (c.gamma - c.alpha * u_) * cur_;
            cur_ += other_;
        } else {
            const Real next = c.alpha * y_ * cur_ - c.beta * other_;
            other_ = cur_;
            cur_ = next;
        }
        ++l_;
        if (std::fabs(cur_) > up()) {  // rare: rescale both carried terms (exact)
            cur_ *= down();
            other_ *= down();
            E_ += T;
            refresh();
        }
    }
    void step() noexcept { step(LambdaCoefficients<Real>::at(l_ + 1, k_)); }

private:
    static SectoralSeed<Real> advance(SectoralSeed<Real> seed, int k) noexcept {
        while (seed.order() < k) seed.next();
        return seed;
    }
    static Real up() noexcept { return std::ldexp(Real(1), T); }
    static Real down() noexcept { return std::ldexp(Real(1), -T); }
    void refresh() noexcept {  // 2^E as a multiplier while it is a normal number
        normal_ = E_ >= std::numeric_limits<Real>::min_exponent - 1;
        factor_ = normal_ ? std::ldexp(Real(1), static_cast<int>(E_)) : Real(0);
    }

    int k_, l_;
    Real y_, u_;
    bool negative_, difference_;
    Real cur_ = 1, other_ = 0;  // Lambda_l mantissa; Lambda_{l-1} or d_l mantissa
    long E_ = 0;
    Real factor_ = 1;
    bool normal_ = true;
};

}  // namespace detail

/// P_l(x) for l = 0..lmax, written to p[0..lmax] (lmax + 1 values). lmax < 0 writes nothing.
/// (The order-0 case of the normalized recurrence, with its difference form near x = +-1.)
template <class Real>
void legendre_p_all(int lmax, Real x, Real* p) noexcept {
    if (lmax < 0) return;
    detail::LambdaStepper<Real> lam(0, x);
    p[0] = lam.value();
    for (int l = 1; l <= lmax; ++l) {
        lam.step();
        p[l] = lam.value();
    }
}

/// P_l(x), one degree (O(l) work). l < 0 returns 0.
template <class Real>
Real legendre_p(int l, Real x) noexcept {
    if (l < 0) return Real(0);
    detail::LambdaStepper<Real> lam(0, x);
    while (lam.degree() < l) lam.step();
    return lam.value();
}

/// Lambda_l^k(x) for l = 0..lmax at fixed order k >= 0, written to out[0..lmax] (zeros for l < k).
/// Allocation-free, O(lmax + k) work. Domain x in [-1, 1] (for |x| > 1 and k > 0 the result is 0).
template <class Real>
void legendre_lambda_all(int k, int lmax, Real x, Real* out) noexcept {
    if (lmax < 0 || k < 0) return;
    for (int l = 0; l < k && l <= lmax; ++l) out[l] = Real(0);
    if (lmax < k) return;
    detail::LambdaStepper<Real> lam(k, x);
    out[k] = lam.value();
    for (int l = k + 1; l <= lmax; ++l) {
        lam.step();
        out[l] = lam.value();
    }
}

/// Lambda_l^k(x), one value (O(l) work, no allocation). Returns 0 unless 0 <= k <= l.
template <class Real>
Real legendre_lambda(int l, int k, Real x) noexcept {
    if (k < 0 || l < k) return Real(0);
    detail::LambdaStepper<Real> lam(k, x);
    while (lam.degree() < l) lam.step();
    return lam.value();
}

}  // namespace stratum
