// stratum/slab.hpp -- a bare scattering slab: its reflection and transmission operators per Fourier mode,
// by the discrete-ordinate method (Stam 2001, Sections 2.3-3; docs/physics.md sections 6-7).
//
// The slab is homogeneous, of single-scattering albedo Omega and optical thickness tau, with index-
// matched (black, non-reflecting) boundaries: light crosses its faces unchanged. Interfaces are composed
// on top of it with the adding equations (adding.hpp).
//
// Discretization. Half-range ordinates mu_1..mu_M in (0, 1] with weights w_m (a half-range rule,
// sum w = 1, such as gauss_legendre_half). The radiance in PROPAGATION directions is expanded as
// L(mu, phi) = sum_k u_k(mu) cos(k phi). With tau measured downward from the top, u+ the upward and u-
// the downward mode-k radiance at the ordinates, the transfer equation becomes
//     d/dtau [u+; u-] = [[-A, -B], [B, A]] [u+; u-],
//     A_nm = (Omega_k w_m p_k(mu_m, mu_n) - delta_nm) / mu_n,   B_nm = Omega_k w_m p_k(-mu_m, mu_n) / mu_n,
//     Omega_k = Omega (1 + delta_k0) / 4,
// with Stam's phase normalization 4 pi p(cos g) = sum_k p_k(mu', mu) cos(k dphi) (so the isotropic
// p_0 = 1, p_k>0 = 0). The (1 + delta_k0)/4 is the azimuthal projection: int cos(k(phi - phi'))
// cos(k phi') dphi' = pi (1 + delta_k0) cos(k phi), divided by Stam's 4 pi.
//
// Symmetric reduction (docs/physics.md section 6). With s = u+ + u-, d = u+ - u-: s'' = (A - B)(A + B) s, and
//     A +- B = -D K(+-) W,   K(+-) = diag(1/w) - Omega_k (P+ +- P-),  D = diag(1/mu), W = diag(w),
// where P+_nm = p_k(mu_m, mu_n), P-_nm = p_k(-mu_m, mu_n) (both symmetric). With G = diag(w/mu) and
// C = diag(sqrt(w mu)), C (A - B)(A + B) C^{-1} = S- S+,  S(+-) = G^{1/2} K(+-) G^{1/2} (symmetric).
// Cholesky S- = L L^T (the odd, K- side: it stays positive definite as Omega -> 1 for any phase function
// the rule resolves, while S+ holds the conservation mode and goes singular), then  L^T S+ L = V diag(lambda^2) V^T  is a symmetric
// eigenproblem. Writing n_j = L v_j and y_j = L^{-T} v_j, the mode decaying as e^{-lambda_j tau} is
//     u+ = C^{-1} (n_j - lambda_j y_j) / 2,   u- = C^{-1} (n_j + lambda_j y_j) / 2,
// and the growing one is its mirror image (u+ and u- exchanged).
//
// Boundary system (Stam's Eq. 15, scaled): every growing mode is written as e^{-lambda (tau_b - tau)},
// so only decaying exponentials E_j = e^{-lambda_j tau_b} <= 1 appear, and the 2M x 2M system stays well
// conditioned for any thickness. For lambda_j tau_b < 1 the pair (decaying, growing) is replaced by
// their sum and their difference divided by lambda_j, which have finite limits as lambda_j -> 0:
//     (n (1 + E) + lambda^2 phi y)  and  (n phi + y (1 + E)),   phi = (1 - E) / lambda -> tau_b.
// This is what makes Omega = 1 exact (the double eigenvalue lambda = 0 at k = 0 has the constant and the
// linear-in-tau solutions) and continuous as Omega -> 1: there the smallest eigenvalue lambda_0^2 ~
// 3 (1 - Omega)(1 - g), below what one eigen-decomposition resolves (~100 eps absolute), is recomputed from the
// structure (refine_conservation_mode; before, a semi-infinite slab's 1 - R at 1 - Omega = 1e-14 was 7.4e-8 for
// 2.9e-7 in double, and float's R 0.99999 for 0.99085 at 1e-5: found by review). At Omega = 1 exactly the zero eigenvalue is set
// to exactly 0 when the discretized phase function conserves energy (sum_m w_m (P+ + P-)_nm = 2).
//
// Accuracy (tests/test_slab.cpp): |R + T - 1| <= 4e-12 at Omega = 1 for M <= 128; the smallest lambda
// to 2e-9 relative at 1 - Omega = 1e-6, and (1 - R) / sqrt(1 - Omega) of a semi-infinite slab steady down to 1e-18;
// entries of R and T carry absolute errors ~1e-16 (so the R ~ tau of
// a very thin slab is good to ~1e-16 / tau relative). The discretization error itself falls only like
// M^-2 on a Gauss rule when the radiance has grazing structure (Chandrasekhar's H: 4e-5, 1e-5, 3e-6 at
// M = 16, 32, 64); rules graded towards mu = 0 converge much faster (the published-table tests use them).
//
// Output convention (shared with the interface operators, docs/physics.md section 5): M x M row-major matrices,
// row n = outgoing ordinate, column m = incoming ordinate, out = L_k in, with
// (L_k)_nm = w_m mu_m int_0^{2 pi} rho(mu_m -> mu_n, phi) cos(k phi) dphi. For the bare slab:
//   reflection   R_k: light entering through the top (travelling down), leaving back up through the top;
//   transmission T_k: light entering through the top, leaving through the bottom, INCLUDING the unscattered
//                beam as the diagonal e^{-tau / mu_m} (exact on the ordinates).
// The slab is mirror-symmetric, so seen from below it has the same R_k and T_k. Directional reflectance
// for incidence at ordinate m is sum_n w_n mu_n R_nm / (w_m mu_m) (mode 0). Reciprocity makes
// R_nm / (w_m mu_m) and T_nm / (w_m mu_m) symmetric.
#pragma once

#include <cmath>
#include <cstddef>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "adding.hpp"
#include "detail/linalg.hpp"
#include "detail/validate.hpp"
#include "quadrature.hpp"

namespace stratum {

/// A homogeneous slab: single-scattering albedo Omega in [0, 1], optical thickness tau in [0, +inf] (+inf:
/// semi-infinite), and a phase function: Henyey-Greenstein of asymmetry g in (-1, 1), or any phase function given
/// by its Legendre moments (with_phase_moments: Rayleigh, tabulated Mie, measured data). Both Omega and 1 - Omega
/// are stored, so a slab built from 1 - Omega (from_one_minus_albedo) keeps values such as 1e-20 that 1 - Omega
/// cannot. Constructors throw std::invalid_argument for values outside these ranges (NaN included).
template <class Real = double>
class Slab {
public:
    Slab(Real albedo, Real g, Real optical_thickness)
        : albedo_(detail::require_closed("albedo", albedo, Real(0), Real(1))),
          one_minus_albedo_(Real(1) - albedo),
          g_(detail::require_open("g", g, Real(-1), Real(1))),
          tau_(require_thickness(optical_thickness)) {}

    /// The slab with Omega = 1 - one_minus_albedo, one_minus_albedo in [0, 1], kept exactly.
    static Slab from_one_minus_albedo(Real one_minus_albedo, Real g, Real optical_thickness) {
        detail::require_closed("one_minus_albedo", one_minus_albedo, Real(0), Real(1));
        Slab s(Real(1) - one_minus_albedo, g, optical_thickness);
        s.one_minus_albedo_ = one_minus_albedo;
        return s;
    }

    /// A phase function given by its Legendre moments chi_l = (1/2) int_{-1}^{1} p(c) P_l(c) dc (the phase
    /// function normalized to 1 over the sphere is sum_l (2l + 1) chi_l P_l(cos theta) / (4 pi)): chi_0 = 1 and
    /// |chi_l| <= 1, as for any phase function; g = chi_1 (0 if only chi_0 is given) must lie in (-1, 1). Moments
    /// beyond those given are 0 (Rayleigh: {1, 0, 0.1}, exactly). The solver uses the first 2M (M ordinates;
    /// delta-M, for g > 0, takes f = chi_2M when it is given, positive and below 1 and leaves every scaled moment
    /// (chi_l - f) / (1 - f) in [-1, 1], and is off otherwise: docs/physics.md section 2).
    static Slab with_phase_moments(Real albedo, std::vector<Real> moments, Real optical_thickness) {
        if (moments.empty()) detail::fail_invalid_argument("stratum: moments is empty (chi_0 = 1 at least)");
        if (!(moments[0] == Real(1))) detail::throw_out_of_range("moments[0]", moments[0], "{1} (a normalized phase function)");
        for (std::size_t l = 1; l < moments.size(); ++l)
            detail::require_closed(("moments[" + std::to_string(l) + "]").c_str(), moments[l], Real(-1), Real(1));
        // g = chi_1 must lie in (-1, 1) (a delta forward or backward): named as the moment given (it said g = 1).
        if (moments.size() > 1 && !(std::fabs(moments[1]) < Real(1)))
            detail::throw_out_of_range("moments[1]", moments[1], "(-1, 1) (g = chi_1)");
        Slab s(albedo, moments.size() > 1 ? moments[1] : Real(0), optical_thickness);
        s.moments_ = std::move(moments);
        return s;
    }

    /// Stam's parametrization by the transparency e^{-tau} in [0, 1] (0: semi-infinite, 1: empty).
    static Slab from_transparency(Real albedo, Real g, Real transparency) {
        detail::require_closed("transparency", transparency, Real(0), Real(1));
        const Real tau = transparency == Real(0) ? std::numeric_limits<Real>::infinity() : -std::log(transparency);
        return Slab(albedo, g, tau);
    }

    Real albedo() const noexcept { return albedo_; }
    Real one_minus_albedo() const noexcept { return one_minus_albedo_; }
    Real g() const noexcept { return g_; }
    Real optical_thickness() const noexcept { return tau_; }
    /// The phase function's Legendre moments as given to with_phase_moments; empty for Henyey-Greenstein.
    const std::vector<Real>& phase_moments() const noexcept { return moments_; }
    bool henyey_greenstein() const noexcept { return moments_.empty(); }

private:
    static Real require_thickness(Real tau) {
        if (!(tau >= Real(0))) detail::throw_out_of_range("optical_thickness", tau, "[0, inf]");
        return tau;
    }
    Real albedo_, one_minus_albedo_, g_, tau_;
    std::vector<Real> moments_;  // empty: Henyey-Greenstein of asymmetry g_
};

/// Reflection and transmission operators of a bare slab for one Fourier mode (see the header comment
/// for the convention). M x M, row-major: reflection[n * size + m] = R_nm.
template <class Real = double>
struct SlabModeOperators {
    std::size_t size = 0;
    std::vector<Real> reflection, transmission;
    Real r(std::size_t n, std::size_t m) const noexcept { return reflection[n * size + m]; }
    Real t(std::size_t n, std::size_t m) const noexcept { return transmission[n * size + m]; }
};

/// A bare slab as a component of the adding equations (adding.hpp): the same seen from above and from below.
template <class Real>
ComponentOperators<Real> slab_component(const SlabModeOperators<Real>& s) {
    ComponentOperators<Real> c;
    c.size = s.size;
    c.reflection_down = c.reflection_up = s.reflection;
    c.transmission_down = c.transmission_up = s.transmission;
    return c;
}

namespace detail {

/// The eigen-solution of one mode: lambda_j >= 0 and the columns n_j = L v_j, y_j = L^{-T} v_j.
template <class Real>
struct SlabEigensystem {
    std::vector<Real> lambda;
    Matrix<Real> n, y;
    bool regularized = false;  // the phase function was aliased on the ordinates and regularized (see regularize)
};

/// Raises the eigenvalues of the symmetric Z = D^{-1/2} S D^{-1/2} = I - Omega_k W^{1/2} P W^{1/2} (P the
/// even or odd part) that lie below -tol to the smallest eigenvalue above tol, and returns the matrix S
/// rebuilt from them; with `factor` it also returns L, L^{-T} of S = L L^T (then every eigenvalue below
/// tol is raised: S must be positive definite). Continuum eigenvalues are 1 - Omega chi_l >= 0; negative
/// ones are aliasing of a phase function too peaked for the M-point rule (|g| -> 1 without delta-M).
/// The change is symmetric and leaves an exact zero eigenvalue (conservation) alone.
template <class Real>
Matrix<Real> regularize(const Matrix<Real>& s, const std::vector<Real>& mu, bool factor, Matrix<Real>* l,
                        Matrix<Real>* l_inverse_transposed) {
    const std::size_t m_size = mu.size();
    Matrix<Real> z(m_size, m_size);
    for (std::size_t i = 0; i < m_size; ++i)
        for (std::size_t j = 0; j < m_size; ++j) z(i, j) = s(i, j) * std::sqrt(mu[i] * mu[j]);
    const SymmetricEigen<Real> ez = symmetric_eigen(z);
    const Real tol = std::sqrt(std::numeric_limits<Real>::epsilon());
    Real floor = Real(1);
    for (const Real v : ez.values)
        if (v > tol) floor = std::fmin(floor, v);
    std::vector<Real> values(m_size);
    for (std::size_t j = 0; j < m_size; ++j) {
        const Real v = ez.values[j];
        values[j] = (factor ? v <= tol : v < -tol) ? floor : v;
    }
    Matrix<Real> rebuilt(m_size, m_size);
    for (std::size_t i = 0; i < m_size; ++i)
        for (std::size_t j = 0; j < m_size; ++j) {
            Real sum = 0;
            for (std::size_t c = 0; c < m_size; ++c) sum += ez.vectors(i, c) * values[c] * ez.vectors(j, c);
            rebuilt(i, j) = sum / std::sqrt(mu[i] * mu[j]);
        }
    if (factor) {
        *l = Matrix<Real>(m_size, m_size);
        *l_inverse_transposed = Matrix<Real>(m_size, m_size);
        for (std::size_t j = 0; j < m_size; ++j) {
            const Real d = std::sqrt(values[j]);
            for (std::size_t i = 0; i < m_size; ++i) {
                const Real sq = std::sqrt(mu[i]);
                (*l)(i, j) = ez.vectors(i, j) * d / sq;                    // L = D^{1/2} U Lambda^{1/2}
                (*l_inverse_transposed)(i, j) = ez.vectors(i, j) * sq / d;  // L^{-T} = D^{-1/2} U Lambda^{-1/2}
            }
        }
    }
    return rebuilt;
}

/// S(+-) = diag(1 / mu) - Omega_k G (P+ +- P-) G, G = diag(sqrt(w / mu)), symmetrized (docs/physics.md
/// section 6). Omega_k = c_k (1 - one_minus_albedo) with the conservative part c_k P kept separate,
/// S = S_c + (1 - Omega) c_k G P G, so that 1 - Omega enters as given.
template <class Real>
void slab_symmetric_parts(Real one_minus_albedo, const std::vector<Real>& mu, const std::vector<Real>& w,
                          const Real* p_same, const Real* p_opposite, int k, Matrix<Real>& s_plus,
                          Matrix<Real>& s_minus) {
    const std::size_t m_size = mu.size();
    const Real ck = k == 0 ? Real(0.5) : Real(0.25);
    std::vector<Real> gs(m_size);
    for (std::size_t i = 0; i < m_size; ++i) gs[i] = std::sqrt(w[i] / mu[i]);
    s_plus = Matrix<Real>(m_size, m_size);
    s_minus = Matrix<Real>(m_size, m_size);
    for (std::size_t i = 0; i < m_size; ++i) {
        for (std::size_t j = 0; j < m_size; ++j) {
            const Real same = (p_same[i * m_size + j] + p_same[j * m_size + i]) / Real(2);
            const Real opp = (p_opposite[i * m_size + j] + p_opposite[j * m_size + i]) / Real(2);
            const Real f = ck * gs[i] * gs[j];
            const Real diag = i == j ? Real(1) / mu[i] : Real(0);
            s_plus(i, j) = (diag - f * (same + opp)) + one_minus_albedo * f * (same + opp);
            s_minus(i, j) = (diag - f * (same - opp)) + one_minus_albedo * f * (same - opp);
        }
    }
}

/// Omega = 1 at k = 0 with a discretely conservative phase function, sum_m w_m (P+ + P-)_nm = 2 to rounding:
/// then K+ w = 0 exactly and lambda_0 = 0 is the conservation mode.
template <class Real>
bool discretely_conservative(Real one_minus_albedo, int k, const std::vector<Real>& w, const Real* p_same,
                             const Real* p_opposite) {
    if (!(one_minus_albedo == Real(0) && k == 0)) return false;
    const std::size_t m_size = w.size();
    Real defect = 0;
    for (std::size_t i = 0; i < m_size; ++i) {
        Real sum = 0;
        for (std::size_t j = 0; j < m_size; ++j) sum += w[j] * (p_same[i * m_size + j] + p_opposite[i * m_size + j]);
        defect = std::fmax(defect, std::fabs(sum / Real(2) - Real(1)));
    }
    return defect <= Real(64) * Real(m_size) * std::numeric_limits<Real>::epsilon();
}

/// The Householder reflection H = I - beta h h^T that maps v / |v| to -sign e_1 (sign: that of v's first entry), and
/// the trailing block of H F H for the symmetric F, indices >= 1: H F H = F - h q^T - q h^T with p = beta F h,
/// q = p - (beta h.p / 2) h.
template <class Real>
struct Reflection {
    std::vector<Real> h;
    Real beta = 0, sign = 1;
    Matrix<Real> trailing;

    /// H x, in place.
    void apply(std::vector<Real>& x) const {
        Real dot = 0;
        for (std::size_t i = 0; i < h.size(); ++i) dot += h[i] * x[i];
        for (std::size_t i = 0; i < h.size(); ++i) x[i] -= beta * dot * h[i];
    }
};

template <class Real>
Reflection<Real> reflection_to_first_axis(const Matrix<Real>& f, const Matrix<Real>& v) {
    const std::size_t m_size = f.rows;
    Reflection<Real> r;
    Real norm = 0;
    for (std::size_t i = 0; i < m_size; ++i) norm += v(i, 0) * v(i, 0);
    norm = std::sqrt(norm);
    r.h.resize(m_size);
    for (std::size_t i = 0; i < m_size; ++i) r.h[i] = v(i, 0) / norm;
    r.sign = r.h[0] >= 0 ? Real(1) : Real(-1);
    r.h[0] += r.sign;
    Real hh = 0;
    for (const Real x : r.h) hh += x * x;
    r.beta = Real(2) / hh;
    std::vector<Real> p(m_size), q(m_size);
    Real hp = 0;
    for (std::size_t i = 0; i < m_size; ++i) {
        Real sum = 0;
        for (std::size_t j = 0; j < m_size; ++j) sum += f(i, j) * r.h[j];
        p[i] = r.beta * sum;
        hp += p[i] * r.h[i];
    }
    for (std::size_t i = 0; i < m_size; ++i) q[i] = p[i] - r.beta * hp / Real(2) * r.h[i];
    r.trailing = Matrix<Real>(m_size - 1, m_size - 1);
    for (std::size_t i = 1; i < m_size; ++i)
        for (std::size_t j = 1; j < m_size; ++j) r.trailing(i - 1, j - 1) = f(i, j) - r.h[i] * q[j] - q[i] * r.h[j];
    return r;
}

/// Eigen-decomposition of the symmetric F with its known null vector v0 deflated analytically: with the reflection
/// H taking v0 to -+|v0| e_1 (reflection_to_first_axis), H F H = [[0, 0], [0, B]]; the eigenvalues are 0 and those
/// of B, the vectors H [[1, 0], [0, V_B]].
template <class Real>
SymmetricEigen<Real> symmetric_eigen_deflated(const Matrix<Real>& f, const Matrix<Real>& v0) {
    const std::size_t m_size = f.rows;
    const Reflection<Real> r = reflection_to_first_axis(f, v0);
    const SymmetricEigen<Real> eb = symmetric_eigen(r.trailing);
    SymmetricEigen<Real> e;
    e.converged = eb.converged;
    e.values.assign(1, Real(0));
    e.values.insert(e.values.end(), eb.values.begin(), eb.values.end());
    e.vectors = Matrix<Real>(m_size, m_size);  // V = H [[1, 0], [0, V_b]]
    std::vector<Real> col(m_size);
    for (std::size_t j = 0; j < m_size; ++j) {
        std::fill(col.begin(), col.end(), Real(0));
        if (j == 0) col[0] = Real(1);
        else
            for (std::size_t i = 1; i < m_size; ++i) col[i] = eb.vectors(i - 1, j - 1);
        r.apply(col);
        for (std::size_t i = 0; i < m_size; ++i) e.vectors(i, j) = col[i];
    }
    return e;
}

/// Mode 0 near conservation (0 < 1 - Omega, a phase function conservative on the ordinates): the smallest eigenvalue
/// of F = L^T S+ L, lambda_0^2 ~ 3 (1 - Omega)(1 - g), lies below what one eigen-decomposition resolves (an absolute
/// error ~100 eps, measured): 1 - Omega = 1e-14 in double gave lambda_0 4.4e-8 for 1.7e-7, and in float from
/// 1 - Omega ~ 1e-3 a semi-infinite slab's R strayed (0.99999 for 0.99085 at 1e-5; found by review). Recomputed from
/// the structure: v0 = L^{-1} c, c = sqrt(w mu), is F's null vector at Omega = 1, and F v0 = L^T S+ c with
/// (S+ c)_n = sqrt(w_n / mu_n) ((1 - s_n) + (1 - Omega) s_n), s_n = c_0 sum_m (P+ + P-)_nm w_m (symmetrized as S+ is),
/// where 1 - s_n, rounding for a phase function conservative on the ordinates, is taken as 0 (as at Omega = 1): every
/// term small and accurate. With the reflection H that maps v0 / |v0| to -+e_1, H F H = [[a, b^T], [b, B]], a and b
/// from F v0, B from F (its eigenvalues are the others, far from 0); the smallest eigenvalue solves
/// x = a - b^T (B - x)^{-1} b, iterated from x = a. Replaces eig's smallest value (its vector and the other pairs
/// stay the decomposition's) only where the iteration converged to the smallest root (B - x positive definite) and
/// B's rounding moves x less than the decomposition's own error.
template <class Real>
void refine_conservation_mode(const Matrix<Real>& f, const Matrix<Real>& l, Real one_minus_albedo, const std::vector<Real>& mu,
                              const std::vector<Real>& w, const Real* p_same, const Real* p_opposite, Real largest,
                              SymmetricEigen<Real>& eig) {
    const std::size_t m_size = mu.size();
    Matrix<Real> c(m_size, 1);
    std::vector<Real> sc(m_size);
    Real c_sc = 0;
    for (std::size_t i = 0; i < m_size; ++i) {
        Real s = 0;
        for (std::size_t j = 0; j < m_size; ++j) {
            const Real same = (p_same[i * m_size + j] + p_same[j * m_size + i]) / Real(2);
            const Real opp = (p_opposite[i * m_size + j] + p_opposite[j * m_size + i]) / Real(2);
            s += (same + opp) * w[j];
        }
        s /= Real(2);  // c_0 = 1/2
        c(i, 0) = std::sqrt(w[i] * mu[i]);
        sc[i] = std::sqrt(w[i] / mu[i]) * one_minus_albedo * s;  // (1 - s_n: rounding, taken as 0, as at Omega = 1)
        c_sc += c(i, 0) * sc[i];
    }
    const Matrix<Real> v0 = solve_lower(l, c);
    Real norm2 = 0;
    for (std::size_t i = 0; i < m_size; ++i) norm2 += v0(i, 0) * v0(i, 0);
    const Real norm = std::sqrt(norm2), a = c_sc / norm2;
    std::vector<Real> fu(m_size);  // F u = L^T (S+ c) / |v0|, u = v0 / |v0|
    for (std::size_t i = 0; i < m_size; ++i) {
        Real sum = 0;
        for (std::size_t j = i; j < m_size; ++j) sum += l(j, i) * sc[j];
        fu[i] = sum / norm;
    }
    // The first column of H F H is H F H e_1 = -sign H F u (H e_1 = -sign u): b its entries from 1 on; B the
    // trailing block, from F.
    const Reflection<Real> r = reflection_to_first_axis(f, v0);
    r.apply(fu);
    std::vector<Real> b(m_size - 1);
    for (std::size_t i = 1; i < m_size; ++i) b[i - 1] = -r.sign * fu[i];
    Real x = a;
    Matrix<Real> t(m_size - 1, 1), shifted(m_size - 1, m_size - 1), factor;
    const auto shift = [&](Real by) {
        for (std::size_t i = 1; i < m_size; ++i)
            for (std::size_t j = 1; j < m_size; ++j) shifted(i - 1, j - 1) = r.trailing(i - 1, j - 1) - (i == j ? by : Real(0));
    };
    bool converged = false;
    for (int iteration = 0; iteration < 16 && !converged; ++iteration) {
        shift(x);
        for (std::size_t i = 0; i + 1 < m_size; ++i) t(i, 0) = b[i];
        t = solve(shifted, t);  // (B - x)^{-1} b
        Real bt = 0;
        for (std::size_t i = 0; i + 1 < m_size; ++i) bt += b[i] * t(i, 0);
        const Real next = a - bt;
        converged = std::fabs(next - x) <= Real(4) * std::numeric_limits<Real>::epsilon() * std::fabs(next);
        x = next;
    }
    // The root sought is the smallest, below every eigenvalue of B: B - x positive definite. Where the decomposition's
    // smallest pair is not the conservation mode (a phase function at the edge of what the ordinates resolve, without
    // delta-M) or b is not small (far from conservation), the iteration found another root or none: R 0 and T 1.44 at
    // 1 - Omega = 5e-3 for g 0.97 without delta-M at M = 16, float garbage at albedos 0.1 to 0.7 (found by review).
    shift(x);
    if (!converged || !cholesky(shifted, factor)) return;
    // Kept only where it is the more accurate: B's absolute error ~ eps max lambda^2 moves x by ~ that times |t|^2,
    // the decomposition's own error in lambda_0^2 is ~100 eps (measured): above max lambda^2 |t|^2 = 100 the latter
    // is kept (float, 32 ordinates, g 0.9, 1 - Omega = 0.1: R 2.9e-3 off with the refined value, within 4e-5 without).
    Real tt = 0;
    for (std::size_t i = 0; i + 1 < m_size; ++i) tt += t(i, 0) * t(i, 0);
    if (!(largest * tt < Real(100))) return;
    // The value alone replaces the decomposition's; its vector stays (H [1; -t] is more accurate, but beside the
    // decomposition's other vectors, which in float mix the two smallest where they are close, it made the basis
    // nearly dependent: g 0.99, M = 32, R 0 and T 1.0003 at 1 - Omega = 2.6e-4; found by review).
    eig.values[0] = std::fmax(x, Real(0));
}

/// Builds S(+-) (slab_symmetric_parts), factors S- = L L^T and solves the symmetric eigenproblem
/// F = L^T S+ L, whose eigenvalues are lambda^2 (docs/physics.md section 6). p_same[n M + m] = p_k(mu_m, mu_n),
/// p_opposite[n M + m] = p_k(-mu_m, mu_n).
template <class Real>
SlabEigensystem<Real> slab_eigensystem(Real one_minus_albedo, const std::vector<Real>& mu, const std::vector<Real>& w,
                                       const Real* p_same, const Real* p_opposite, int k,
                                       bool regularize_aliased_phase = false) {
    const std::size_t m_size = mu.size();
    Matrix<Real> s_plus, s_minus;
    slab_symmetric_parts(one_minus_albedo, mu, w, p_same, p_opposite, k, s_plus, s_minus);
    // Factor S- = L L^T: Cholesky when S- is positive definite (always for a phase function the rule
    // resolves); otherwise refuse (std::domain_error), or, if asked, regularize the odd part (see
    // regularize; L is then not triangular).
    Matrix<Real> l, l_inverse_transposed;
    const bool triangular = cholesky(s_minus, l);
    if (!triangular) {
        if (!regularize_aliased_phase)
            detail::fail_domain_error("stratum: slab mode " + std::to_string(k) +
                                    ": the discretized phase function is not admissible on these ordinates "
                                    "(S- is not positive definite: too peaked for M ordinates; use delta-M scaling)");
        regularize(s_minus, mu, true, &l, &l_inverse_transposed);
    }

    // Omega = 1 at k = 0 with a discretely conservative phase function: F = L^T S+ L has the null vector
    // v0 = L^{-1} sqrt(w mu), and lambda_0 = 0 is set exactly. In the aliased regime (regularized factors),
    // where other eigenvalues crowd 0, v0 is also deflated analytically (symmetric_eigen_deflated): energy is
    // then conserved to ~1e-14 instead of ~1e-8. (Deflating always would cost accuracy at grazing ordinates
    // for large M: 2e-10 instead of 4e-12 at M = 128, measured.)
    const bool conservative = discretely_conservative(one_minus_albedo, k, w, p_same, p_opposite);
    bool deflate = !triangular;
    Matrix<Real> f;  // F = L^T S+ L, symmetrized
    auto eigen_of_f = [&]() {
        f = multiply(transpose(l), multiply(s_plus, l));
        for (std::size_t i = 0; i < m_size; ++i)
            for (std::size_t j = 0; j < i; ++j) f(i, j) = f(j, i) = (f(i, j) + f(j, i)) / Real(2);
        if (!conservative || !deflate) return symmetric_eigen(f);
        Matrix<Real> c(m_size, 1);
        for (std::size_t i = 0; i < m_size; ++i) c(i, 0) = std::sqrt(w[i] * mu[i]);
        return symmetric_eigen_deflated(f, triangular ? solve_lower(l, c) : multiply(transpose(l_inverse_transposed), c));
    };
    SymmetricEigen<Real> eig = eigen_of_f();
    // lambda^2 >= 0 up to rounding (~ M eps max|lambda^2|) unless the even part is aliased too: then
    // regularize S+ the same way and solve again.
    Real largest = 0, smallest = 0;
    for (const Real v : eig.values) largest = std::fmax(largest, std::fabs(v)), smallest = std::fmin(smallest, v);
    if (smallest < -Real(64) * Real(m_size) * std::numeric_limits<Real>::epsilon() * largest) {
        s_plus = regularize<Real>(s_plus, mu, false, nullptr, nullptr);
        deflate = true;
        eig = eigen_of_f();
    }

    // Near conservation (mode 0, 0 < 1 - Omega, lambda_0^2 below 1e4 sqrt(eps), 1.5e-4 in double, where the
    // decomposition's ~100 eps is a relative 1.5e-10, and below an eighth of the next eigenvalue, so that the
    // smallest pair is the conservation mode) the smallest eigenvalue is recomputed from the structure
    // (refine_conservation_mode): R and T continuous into Omega = 1. Not where the decomposition's vectors of the
    // two smallest values are mixed (their error ~ eps max(lambda^2) / lambda_1^2 above 2: float, g 0.99 with
    // delta-M, M = 32, where the exact value beside the mixed vector was 2.3 times further from long double, 4.8e-4
    // at tau 100, than the decomposition's own; the bound 2 keeps g 0.9 at M = 32, 3.3e-5 where it was 2.7e-3). Measured against long double, the directional
    // albedo at every ordinate of a semi-infinite slab (g 0, 1 - Omega 1e-9 to 0.5, 400 values): float within 8.6e-5
    // at M = 16 and 3.0e-4 at M = 32 (before: 1.5e-2 and 2.1e-2), double 2.7e-11 at M = 32 (5.3e-9; and 0.75 of 1 - R
    // at 1 - Omega = 1e-14, where the slab was treated as lossless below ~1e-16).
    if (k == 0 && one_minus_albedo > 0 && triangular && !deflate && m_size > 1 &&
        eig.values[0] < Real(1e4) * std::sqrt(std::numeric_limits<Real>::epsilon()) && eig.values[0] < eig.values[1] / 8 &&
        std::numeric_limits<Real>::epsilon() * largest < 2 * eig.values[1] &&
        discretely_conservative(Real(0), k, w, p_same, p_opposite))
        refine_conservation_mode(f, l, one_minus_albedo, mu, w, p_same, p_opposite, largest, eig);

    SlabEigensystem<Real> out;
    out.regularized = deflate;  // (S- or S+ regularized)
    out.lambda.resize(m_size);
    for (std::size_t j = 0; j < m_size; ++j) out.lambda[j] = std::sqrt(std::fmax(eig.values[j], Real(0)));
    if (conservative && !deflate) {
        std::size_t zero = 0;  // the eigenvalue nearest 0 is the conservation mode
        for (std::size_t j = 1; j < m_size; ++j)
            if (std::fabs(eig.values[j]) < std::fabs(eig.values[zero])) zero = j;
        out.lambda[zero] = Real(0);
    }
    out.n = multiply(l, eig.vectors);
    out.y = triangular ? solve_lower_transposed(l, eig.vectors) : multiply(l_inverse_transposed, eig.vectors);
    return out;
}

/// The scaled boundary-value problem of a bare slab with black boundaries and unit radiance entering at
/// each ordinate in turn; returns R and T in the scaled variables R~ = C R C^{-1}, C = diag(sqrt(w mu)).
template <class Real>
void slab_boundary_solve(const SlabEigensystem<Real>& es, Real tau, Matrix<Real>& r_scaled, Matrix<Real>& t_scaled) {
    const std::size_t m_size = es.lambda.size();
    if (std::isinf(tau)) {  // semi-infinite: R~ = P~ Q~^{-1}, P~ = N - Y Lambda, Q~ = N + Y Lambda
        Matrix<Real> pt(m_size, m_size), qt(m_size, m_size);
        for (std::size_t i = 0; i < m_size; ++i)
            for (std::size_t j = 0; j < m_size; ++j) {
                const Real ly = es.lambda[j] * es.y(i, j);
                pt(i, j) = es.n(i, j) - ly;
                qt(i, j) = es.n(i, j) + ly;
            }
        // R~ Q~ = P~  <=>  Q~^T R~^T = P~^T
        r_scaled = transpose(solve(transpose(qt), transpose(pt)));
        t_scaled = Matrix<Real>(m_size, m_size);
        return;
    }
    // The slab is the same seen from either face, so the 2M x 2M system for the mode coefficients splits into two
    // M x M systems: its columns combined into parts even and odd under exchanging the faces (a decaying-growing
    // pair's sum and difference; a pair with lambda tau < 1 is already written as such a sum and difference),
    // unit radiance at ordinate i entering the top face is half even (entering both faces) and half odd. With
    // A_e, A_o the parts' incoming radiance at one face and O_e, O_o their outgoing radiance there,
    //     R~ = (O_e A_e^-1 + O_o A_o^-1) / 2,   T~ = (O_e A_e^-1 - O_o A_o^-1) / 2,
    // each X = O A^-1 solved as A^T X^T = O^T: ~ 5 M^3 flops where the coupled system took ~ 17 M^3.
    Matrix<Real> in_even(m_size, m_size), in_odd(m_size, m_size), out_even(m_size, m_size), out_odd(m_size, m_size);
    for (std::size_t j = 0; j < m_size; ++j) {  // (transposed: row j is mode j's column)
        const Real lam = es.lambda[j];
        const Real x = lam * tau;
        const Real e = std::exp(-x);
        Real* ie = in_even.row(j);
        Real* io = in_odd.row(j);
        Real* oe = out_even.row(j);
        Real* oo = out_odd.row(j);
        if (x >= Real(1)) {  // the decaying mode (p going out, q coming in at its face) and the growing one, mirrored
            for (std::size_t i = 0; i < m_size; ++i) {
                const Real n = es.n(i, j), ly = lam * es.y(i, j);
                const Real p = n - ly, q = n + ly;
                ie[i] = q + p * e;
                io[i] = q - p * e;
                oe[i] = p + q * e;
                oo[i] = p - q * e;
            }
        } else {  // sum and scaled difference of the pair, finite as lambda -> 0
            const Real phi = lam == Real(0) ? tau : -std::expm1(-x) / lam;
            const Real l2phi = lam * lam * phi;
            // The difference may be scaled freely (its unknown coefficient absorbs the factor): for phi > 1 it is
            // divided by phi. Otherwise the conservation mode (Omega = 1, lambda = 0, phi = tau) of a very thick
            // slab has entries ~ tau: lu_factor's singularity threshold, relative to the largest entry, then treats
            // every O(1) pivot as zero (tau = 1e300 gave R + T = 8e-8 instead of 1), and tau ~ 1e308 overflows.
            // Scaled, tau -> inf tends to the semi-infinite solution (tests/test_layer_inputs.cpp).
            const Real big = phi > Real(1) ? phi : Real(1);
            const Real n_phi = phi > Real(1) ? Real(1) : phi, y_scale = (Real(1) + e) / big;
            for (std::size_t i = 0; i < m_size; ++i) {
                const Real n = es.n(i, j), y = es.y(i, j);
                ie[i] = n * (Real(1) + e) + l2phi * y;
                oe[i] = n * (Real(1) + e) - l2phi * y;
                io[i] = n * n_phi + y * y_scale;
                oo[i] = n * n_phi - y * y_scale;
            }
        }
    }
    lu_solve(lu_factor(std::move(in_even)), out_even);  // X_e^T
    lu_solve(lu_factor(std::move(in_odd)), out_odd);    // X_o^T
    r_scaled = Matrix<Real>(m_size, m_size);
    t_scaled = Matrix<Real>(m_size, m_size);
    for (std::size_t i = 0; i < m_size; ++i)
        for (std::size_t l = 0; l < m_size; ++l) {
            r_scaled(i, l) = (out_even(l, i) + out_odd(l, i)) / Real(2);
            t_scaled(i, l) = (out_even(l, i) - out_odd(l, i)) / Real(2);
        }
}

template <class Real>
void check_ordinates(const Quadrature<Real>& q) {
    if (q.nodes.empty()) detail::fail_invalid_argument("stratum: the ordinate set is empty");
    if (q.weights.size() != q.nodes.size())
        detail::fail_invalid_argument("stratum: ordinates and weights differ in number");
    for (std::size_t i = 0; i < q.size(); ++i) {
        if (!(q.nodes[i] > Real(0) && q.nodes[i] <= Real(1))) throw_out_of_range("ordinate", q.nodes[i], "(0, 1]");
        require_positive("ordinate weight", q.weights[i]);
    }
}

}  // namespace detail

namespace detail {

/// One mode of a bare slab as solved: whether it scatters (if not, R = 0 and T = diag(e^{-tau/mu}), or T = I at
/// tau = 0, with no eigen-solution), and otherwise its eigen-solution and the scaled R~ = C R C^{-1}, T~ = C T C^{-1},
/// C = diag(sqrt(w mu)). The beam source (detail/beam_source.hpp) needs all three.
template <class Real>
struct SlabModeSolution {
    bool scatters = false;
    SlabEigensystem<Real> eigen;
    Matrix<Real> r_scaled, t_scaled;
};

template <class Real>
SlabModeSolution<Real> slab_mode_solution(const Slab<Real>& slab, const Quadrature<Real>& ordinates, const Real* p_same,
                                          const Real* p_opposite, int k, bool regularize_aliased_phase) {
    SlabModeSolution<Real> out;
    const std::size_t m_size = ordinates.size();
    const Real tau = slab.optical_thickness();
    if (tau == Real(0) || !(slab.one_minus_albedo() < Real(1))) return out;
    for (std::size_t i = 0; i < m_size * m_size && !out.scatters; ++i)
        out.scatters = p_same[i] != Real(0) || p_opposite[i] != Real(0);
    if (!out.scatters) return out;
    out.eigen = slab_eigensystem(slab.one_minus_albedo(), ordinates.nodes, ordinates.weights, p_same, p_opposite, k,
                                 regularize_aliased_phase);
    slab_boundary_solve(out.eigen, tau, out.r_scaled, out.t_scaled);
    return out;
}

/// R and T of a solved mode (see SlabModeSolution).
template <class Real>
SlabModeOperators<Real> slab_mode_operators(const SlabModeSolution<Real>& solution, const Quadrature<Real>& ordinates,
                                            Real tau) {
    const std::size_t m_size = ordinates.size();
    SlabModeOperators<Real> out;
    out.size = m_size;
    out.reflection.assign(m_size * m_size, Real(0));
    out.transmission.assign(m_size * m_size, Real(0));
    if (!solution.scatters) {  // only the unscattered beam (all of it at tau = 0)
        for (std::size_t i = 0; i < m_size; ++i)
            out.transmission[i * m_size + i] = std::isinf(tau) ? Real(0) : std::exp(-tau / ordinates.nodes[i]);
        return out;
    }
    std::vector<Real> c(m_size);
    for (std::size_t i = 0; i < m_size; ++i) c[i] = std::sqrt(ordinates.weights[i] * ordinates.nodes[i]);
    for (std::size_t i = 0; i < m_size; ++i)
        for (std::size_t j = 0; j < m_size; ++j) {
            const Real scale = c[j] / c[i];
            out.reflection[i * m_size + j] = solution.r_scaled(i, j) * scale;
            out.transmission[i * m_size + j] = solution.t_scaled(i, j) * scale;
        }
    return out;
}

}  // namespace detail

/// Reflection and transmission operators of a bare slab for Fourier mode k >= 0.
///   ordinates:  half-range rule on (0, 1] (e.g. gauss_legendre_half<Real>(M)), weights > 0;
///   p_same:     M x M row-major, p_same[n M + m] = p_k(mu_m, mu_n)   (Stam's normalization, see top);
///   p_opposite: M x M row-major, p_opposite[n M + m] = p_k(-mu_m, mu_n).
/// The phase matrices are those of the slab's phase function (e.g. henyey_greenstein.hpp with the
/// slab's g, or delta-M scaled moments together with a scaled Slab); slab.g() itself is not read here.
/// For energy conservation at Omega = 1 the discrete phase function must conserve energy (a Legendre
/// expansion truncated at degree <= 2M - 1 does, on a Gauss rule).
/// Special cases, exact: tau = 0 gives R = 0, T = I; Omega = 0, or a mode whose phase matrices vanish,
/// gives R = 0, T = diag(e^{-tau/mu}) with no eigen-solve; tau = +inf gives the semi-infinite R and T = 0.
/// Cost: ~ 17 M^3 flops for the eigen-solution (Cholesky, congruence, Householder + QL with vectors) plus
/// ~ 5 M^3 for the boundary system, split into its parts even and odd under exchanging the faces (semi-infinite:
/// ~ 3 M^3).
/// Strongly peaked phase functions that M ordinates cannot resolve (e.g. g = 0.99 without delta-M, M < 64)
/// alias on the rule: the odd-part operator S- loses positive definiteness (its continuum eigenvalues
/// 1 - Omega chi_l become <= 0). Then, by default, std::domain_error is thrown (the remedy is delta-M
/// scaling or more ordinates); with regularize_aliased_phase = true the offending eigenvalues are raised
/// instead (detail::regularize) and the result stays finite and energy-conserving -- but note that the cut
/// series itself is negative in places then (Gibbs), and so may R be. Aliasing of the even part alone
/// (S+, lambda^2 < 0) is always regularized.
/// Throws std::invalid_argument for an invalid ordinate set or k < 0.
template <class Real>
SlabModeOperators<Real> solve_slab_mode(const Slab<Real>& slab, const Quadrature<Real>& ordinates,
                                        const Real* p_same, const Real* p_opposite, int k,
                                        bool regularize_aliased_phase = false) {
    detail::check_ordinates(ordinates);
    detail::require_count("k", k, 0);
    return detail::slab_mode_operators(
        detail::slab_mode_solution(slab, ordinates, p_same, p_opposite, k, regularize_aliased_phase), ordinates,
        slab.optical_thickness());
}

/// Overload taking the phase matrices as std::vector (size M * M each).
template <class Real>
SlabModeOperators<Real> solve_slab_mode(const Slab<Real>& slab, const Quadrature<Real>& ordinates,
                                        const std::vector<Real>& p_same, const std::vector<Real>& p_opposite, int k,
                                        bool regularize_aliased_phase = false) {
    const std::size_t need = ordinates.size() * ordinates.size();
    if (p_same.size() != need || p_opposite.size() != need)
        detail::fail_invalid_argument("stratum: phase matrices must be M x M for M ordinates");
    return solve_slab_mode(slab, ordinates, p_same.data(), p_opposite.data(), k, regularize_aliased_phase);
}

}  // namespace stratum
