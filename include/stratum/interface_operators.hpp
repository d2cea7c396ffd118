// stratum/interface_operators.hpp -- the Fourier-mode operators R_12, T_12, R_21, T_21 of a dielectric
// interface (rough, smooth or index matched) on discrete ordinates, for the layer solver (docs/physics.md
// section 5). The conventions (kernels in propagation terms, I_k, L_k, energy and reciprocity) and the
// azimuthal rule are those of azimuthal_quadrature.hpp.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <optional>
#include <type_traits>
#include <utility>
#include <vector>

#include "azimuthal_quadrature.hpp"
#include "detail/math.hpp"
#include "detail/validate.hpp"
#include "interface.hpp"
#include "quadrature.hpp"
#include "vec3.hpp"

namespace stratum {

// ------------------------------------------------------------------------------------------------
// Dielectric interfaces.
//
// Four operators per interface (media 1 above, 2 below; "12" = light arriving from above):
//   R_12 light from above reflected up,     T_12 light from above transmitted down,
//   R_21 light from below reflected down,   T_21 light from below transmitted up.
// Propagation-direction adapter (the same for all four): the incident propagation direction has azimuth 0,
//   from above: wi = (-s_in, 0, mu_in);   from below: wi = (-s_in, 0, -mu_in)   (wi points away, pbrt),
//   outgoing:   wo = (s_out cos phi, s_out sin phi, +-mu_out), + for light leaving upwards,
// with s = sqrt(1 - mu^2), and rho = RoughDielectric::brdf(wi, wo) or btdf(wi, wo) (evaluated as facet_brdf or
// facet_btdf times shadowing_over_cosines, the second once per pair of cosines: equal within a few ulp). (This equals
// RoughDielectric::eval_propagation; building wo from cos and sin phi separately keeps full accuracy for
// lobes narrower than 1e-4 rad, where sin phi recovered from cos phi would not.)
//
// Lobe width in phi (exact for the Beckmann factor D, which is exp(kappa cos phi) times a slowly varying
// function of phi; the width is 1 / sqrt(kappa)). With p the facet slope selecting the outgoing direction,
// |p|^2 = (A - B cos phi) / C, D ~ exp(-|p|^2 / (2 sigma^2)), so kappa = B / (2 sigma^2 C):
//   reflection:               width = sigma (mu_in + mu_out) / sqrt(s_in s_out),
//   transmission (eta_i -> eta_o): width = sigma |eta_i mu_in - eta_o mu_out| / sqrt(eta_i eta_o s_in s_out).
// At normal incidence or exit (s = 0) rho does not depend on phi (width = pi).
//
// Special interfaces, represented exactly rather than discretized:
//  * index matching (eta_above == eta_below; RoughDielectric or SmoothDielectric): the BTDF is a delta,
//    T_12 = T_21 = identity and R = 0 in every mode.
//  * SmoothDielectric (sigma = 0): R_k = diag(F(mu_m)) in every mode (specular reflection maps each
//    ordinate onto itself at phi = 0). Transmission maps mu to the Snell cosine mu_t (same in every mode),
//    which is in general not an ordinate. Documented choices (SpecularTransmission), measured for
//    n 1 | 1.4 in tests/test_interface_operators.cpp:
//    - pointwise (DEFAULT): row n holds (n_t/n_i)^2 (1 - F(mu_i)) times the weights interpolating the
//      incident field at mu_i = Snell^{-1}(mu_n) from the p nearest ordinates (default 4: exact for cubic
//      fields in mu; the end window extrapolates, so entries down to ~ -0.13 occur). Radiance-accurate and
//      convergent; energy holds to the accuracy of the Gauss rule: leaving the denser medium the flux of a
//      uniform field is exact to rounding, entering it the flux is off by 2.5e-2 at M = 24 and 1.9e-3 at
//      M = 64 (the integrand over the transmitted cosine jumps at the critical cosine). Per incident
//      ordinate (column) the flux is not conserved (interpolation weights do not integrate to w_m).
//    - flux_conserving: column m carries the beam of ordinate m, power 1 - F(mu_m), to the p ordinates
//      around mu_t(mu_m) with local Lagrange weights s_n (sum 1; default p = 2: linear, non-negative),
//          T_{n,m} = w_m mu_m (1 - F(mu_m)) s_n(mu_t) / (w_n mu_n),
//      so sum_n w_n mu_n T_{n,m} = w_m mu_m (1 - F(mu_m)): R + T = 1 per incident ordinate exactly (a
//      non-absorbing stack stays exactly conservative), T >= 0. Images beyond the outermost ordinates are
//      clamped to them. But the transmitted radiance is right only on average: each ordinate collects a
//      varying share of beams, so rows are off by 4-9% inside the cone at M = 24..64 (not converging)
//      and by ~20% next to the critical cosine and at the last ordinate; leaving the denser medium the
//      expanding map leaves ordinates without beams (errors of order 1). Use it for energy bookkeeping.
//    - automatic: flux_conserving into the denser medium (where the map compresses), pointwise out of it.
//    Under generalized reciprocity the two constructions are transposes of each other (apart from the
//    ends, T12 pointwise is the reciprocal of T21 flux_conserving with the same window); with one set of
//    Gauss ordinates on both sides of a critical cone, exact reciprocity, exact energy and pointwise
//    accuracy cannot all hold (the two sides' Gauss sums of the total transmittance differ).
//    Ordinates beyond the critical angle inside the denser medium are totally reflected (R = 1, T column
//    = 0, T row = 0) in both modes: beams landing between the critical cosine and the first ordinate above
//    it go to that ordinate (and the ones above), and pointwise interpolation reads only ordinates above the
//    critical cosine (extrapolating to it), so no light crosses into or out of a totally reflected
//    direction (between two lossless faces it would be trapped; tests/test_layer_inputs.cpp). A solver that
//    needs exact beams should keep the unscattered beam analytic (docs/physics.md section 6).
//
// Accuracy of the rough operators. The phi integral is controlled by AzimuthalQuadrature (measured: <= 4e-12
// relative for sigma in {1, 0.3, 0.02} with the default 24 points per panel and 48 modes, ~1e-15 for analytic
// lobes; with few modes the rule has few panels, and a branch point of F near phi = 0 off the real axis is felt:
// 1.0e-7 relative with one mode at sigma 1, n 1 | 1.4, M = 24, found by review; coefficients() gives more).
// The mu direction is sampled only at the ordinates: energy (flux-weighted column sums, see the top of this
// file) matches the hemispherical totals only when the lobe is wide compared with the ordinate spacing
// (sigma = 0.3, n 1 | 1.4: max error 3e-4 (T12) and 2e-3 (R21, TIR onset) at M = 24, 8e-6 and 4e-4 at
// M = 64); for narrow lobes (sigma = 0.02) the matrices are pointwise right but the Gauss sum over mu_out
// misses or over-counts the lobe (errors of order 1 at M = 24). The coefficient functions at arbitrary
// angles stay accurate for any sigma (they integrate to RoughDielectric::hemispherical_totals to ~1e-11 at sigma = 0.02).
// A nearly index-matched rough interface has a BTDF lobe narrower than the ordinate spacing: at sigma = 0.3,
// M = 24 the T12 column fluxes are off by 1.7e-2 at n 1 | 1.2, 0.37 at 1.1, 10 at 1.01 (the coefficient
// functions stay accurate). Exact matching is detected and represented as the identity; near it, use
// Renormalization::hemispherical_totals (energy per column exact, T -> identity as eta -> 1) or more ordinates.

/// Which side the light arrives from: from_above = travelling downwards (operators *_12).
enum class Incidence { from_above, from_below };

/// Optional energy correction of the rough operators (see InterfaceOperators).
enum class Renormalization {
    none,                 ///< the operators as defined (pointwise in mu_out); InterfaceOperators' default
    hemispherical_totals  ///< each column scaled to the interface's hemispherical R or T for its ordinate;
                          ///< LayerOptions' default (the layer solver's)
};

/// How a smooth interface's Snell-mapped transmission is put on the ordinates (see the comment above).
enum class SpecularTransmission {
    pointwise,        ///< each outgoing ordinate interpolates the incident field at its Snell pre-image;
                      ///< InterfaceOperators' default
    flux_conserving,  ///< each incident ordinate's beam split over the ordinates around its Snell image
    automatic         ///< flux_conserving into the denser medium, pointwise out of it; LayerOptions' default
                      ///< (whose interior faces of a stack are always flux_conserving, see solve_stack)
};

namespace detail {

// The BSDF of a rough interface in propagation terms (see above), for one incidence side and lobe.
template <class Real>
struct RoughKernel {
    const RoughDielectric<Real>* interface;
    Incidence incidence;
    bool transmission;

    Real operator()(Real mu_in, Real mu_out, Real c, Real s) const noexcept { return at(mu_in, mu_out)(mu_in, mu_out, c, s); }

    // The kernel of one pair of cosines, its shadowing factor computed once (RoughDielectric::facet_brdf): the
    // shadowing (two Lambdas, and for the height-correlated transmission a Beta function) cost more than the rest
    // of an evaluation, and an azimuthal integral evaluates the pair at some 200 azimuths.
    struct Pair {
        const RoughDielectric<Real>* interface;
        bool transmission;
        Vec3<Real> wi;
        Real s_out, z_out;
        wide_t<Real> shadowing;  // G2 / (mu_in mu_out); not finite: evaluate brdf or btdf whole
        Real operator()(Real, Real, Real c, Real s) const noexcept {
            const Vec3<Real> wo{s_out * c, s_out * s, z_out};
            if (!std::isfinite(shadowing)) return transmission ? interface->btdf(wi, wo) : interface->brdf(wi, wo);
            const wide_t<Real> f = transmission ? interface->facet_btdf(wi, wo) : interface->facet_brdf(wi, wo);
            return f > 0 ? saturate_to<Real>(f * shadowing) : Real(0);
        }
    };
    Pair at(Real mu_in, Real mu_out) const noexcept {
        const Real s_in = std::sqrt(std::fmax(Real(0), (1 - mu_in) * (1 + mu_in)));
        const Real s_out = std::sqrt(std::fmax(Real(0), (1 - mu_out) * (1 + mu_out)));
        const Real z_in = incidence == Incidence::from_above ? mu_in : -mu_in;
        const bool out_up = (incidence == Incidence::from_above) != transmission;
        return {interface, transmission, Vec3<Real>{-s_in, Real(0), z_in}, s_out, out_up ? mu_out : -mu_out,
                interface->shadowing_over_cosines(mu_in, mu_out, transmission)};
    }

    AzimuthalFeatures<Real> features(Real mu_in, Real mu_out) const noexcept {
        const Real pi = detail::pi_v<Real>;
        const Real s_in = std::sqrt(std::fmax(Real(0), (1 - mu_in) * (1 + mu_in)));
        const Real s_out = std::sqrt(std::fmax(Real(0), (1 - mu_out) * (1 + mu_out)));
        const bool above = incidence == Incidence::from_above;
        const Real eta_i = above ? interface->eta_above() : interface->eta_below();
        const Real eta_o = above ? interface->eta_below() : interface->eta_above();
        const Real ss = s_in * s_out;
        Real numerator, denominator;
        if (transmission) {
            numerator = interface->sigma() * std::fabs(eta_i * mu_in - eta_o * mu_out);
            denominator = std::sqrt(eta_i * eta_o * ss);
        } else {
            numerator = interface->sigma() * (mu_in + mu_out);
            denominator = std::sqrt(ss);
        }
        AzimuthalFeatures<Real> out(numerator < pi * denominator ? numerator / denominator : pi);  // s = 0: pi
        if (!(ss > 0)) {  // rho does not depend on phi
            out.analytic_strip = std::numeric_limits<Real>::infinity();
            return out;
        }
        out.analytic_strip = analytic_strip(transmission, eta_i, eta_o, mu_in * mu_out, ss);
        // Breakpoint where x = wi.wo (= -s_in s_out cos phi +- mu_in mu_out) reaches the value x* at which
        // the facet that connects wi and wo starts or stops refracting:
        //   transmission: o.h = 0 or i.h = 0, i.e. x* = -min(eta_i/eta_o, eta_o/eta_i) (kink / TIR onset);
        //   reflection inside the denser medium: i.h = sqrt((1 + x)/2) = cos(critical), x* = 1 - 2 (eta_o/eta_i)^2.
        Real cos_break;
        if (transmission) {
            const Real r = std::fmin(eta_i / eta_o, eta_o / eta_i);
            cos_break = (r - mu_in * mu_out) / ss;
        } else {
            if (!(eta_o < eta_i)) return out;
            const Real e = eta_o / eta_i;
            cos_break = (mu_in * mu_out - 1 + 2 * e * e) / ss;
        }
        if (cos_break > -1 && cos_break < 1) out.add_break(std::acos(cos_break));
        return out;
    }

    // The half-width of the strip |Im phi| < a in which rho(phi) is analytic (0 where a singular point is real).
    // As a function of x = wi.wo = -s_in s_out cos phi +- mu_in mu_out (+ reflection, - transmission), rho is
    // analytic (the Beckmann factor and 1 / cos^4 of the facet normal are entire in x; the shadowing depends on
    // the cosines alone) except where
    //   reflection:   the half vector vanishes, x = -1 (i.h = 0), and the Fresnel factor's branch point
    //                 (cos_t = 0), x = 1 - 2 (eta_o / eta_i)^2;
    //   transmission: i.h = 0 or o.h = 0, x = -eta_o / eta_i or -eta_i / eta_o (|.| and the Fresnel branch),
    //                 and |eta_i wi + eta_o wo| = 0, x = -(r + 1 / r) / 2, r = eta_i / eta_o.
    // A value of x maps to cos phi* = (+-mu_in mu_out - x) / (s_in s_out); where |cos phi*| > 1 the singular
    // point lies at Im phi = acosh |cos phi*| (above phi = 0 or pi). (Omitting x = -1 leaves the trapezoid rule's
    // coefficients off by 3.4e-5 of the largest in tests/test_interface_operators.cpp's sweep. The points i.h = 0 and
    // o.h = 0 are singular points of the formulas; whether the kernel, zero on one side of them, needs them is not
    // settled: their omission gave 1.5e-9 on a wider sweep (M 40, sigma 0.05) and nothing in the test's, and a
    // reviewer found none either. They are kept.)
    static Real analytic_strip(bool transmission, Real eta_i, Real eta_o, Real mu_mu, Real ss) noexcept {
        Real x[3];
        int count = 0;
        if (transmission) {
            const Real r = eta_i / eta_o;
            x[count++] = -r;
            x[count++] = -1 / r;
            x[count++] = -(r + 1 / r) / 2;
        } else {
            const Real e = eta_o / eta_i;
            x[count++] = -1;
            x[count++] = 1 - 2 * e * e;
        }
        Real strip = std::numeric_limits<Real>::infinity();
        for (int i = 0; i < count; ++i) {
            const Real y = std::fabs(((transmission ? -mu_mu : mu_mu) - x[i]) / ss) - 1;  // |cos phi*| - 1
            if (!(y > 0)) return Real(0);
            strip = std::fmin(strip, std::log1p(y + std::sqrt(y * (y + 2))));  // acosh(1 + y)
        }
        return strip;
    }
};

}  // namespace detail

/// The Fourier-mode operators R_12, T_12, R_21, T_21 of a dielectric interface on given ordinates, and
/// (for a rough interface) the raw coefficients I_k at arbitrary angles. See the comments above for the
/// conventions, the adapter, and how index matching and smooth interfaces are represented.
template <class Real = double>
class InterfaceOperators {
public:
    /// Rough interface: the operators of the interface's BRDF/BTDF as fourier_operators would build them,
    /// with reciprocity used to halve the work when the shadowing is reciprocal (every model but
    /// Shadowing::masking_only; index matching: identity / zero, exactly).
    /// Cost ~2 M^2 x (phi samples) x (K + BSDF evaluation).
    /// renormalization = hemispherical_totals scales every column (all modes alike) so that its flux equals
    /// RoughDielectric::hemispherical_totals at that ordinate, blended with the specular column carrying the total to the
    /// mirror/Snell image (split linearly between the two ordinates around it; the same in every mode: a
    /// delta in phi) by the share 1 - min(r, 1/r), r = captured flux / total: a resolved lobe (r ~ 1) is kept,
    /// one that passes between the ordinates (r -> 0 or large) becomes specular, continuously in every
    /// parameter. Energy then holds per incident ordinate for any lobe width, and as
    /// eta -> 1 or sigma -> 0 the operators tend to the specular ones (T -> identity at matching). The
    /// price: reciprocity of the matrices is lost (to the size of the correction), the lobe shape in mu
    /// is still only sampled, and 2M hemispherical_totals integrals are added.
    /// `totals_nodes`: the Gauss nodes per panel of the renormalization's integrals (RoughDielectric::hemispherical_totals,
    /// 2 to 32).
    /// Throws std::invalid_argument for modes < 1, an empty ordinate set or totals_nodes outside [2, 32].
    InterfaceOperators(const RoughDielectric<Real>& interface, const Quadrature<Real>& ordinates, int modes,
                       const AzimuthalQuadrature<Real>& rule = AzimuthalQuadrature<Real>(),
                       Renormalization renormalization = Renormalization::none, int totals_nodes = 16)
        : rough_(interface), rule_(rule), modes_(detail::require_count("modes", modes, 1)),
          index_matched_(interface.index_matched()), specular_(interface.index_matched()) {
        detail::require_count("ordinates", static_cast<int>(ordinates.size()), 1);
        if (totals_nodes < 2 || totals_nodes > 32) detail::throw_out_of_range("totals_nodes", totals_nodes, "[2, 32]");
        const int m = static_cast<int>(ordinates.size());
        if (index_matched_) {
            set_index_matched(m);
            return;
        }
        if (interface.smooth()) {
            // sigma below RoughDielectric::smooth_sigma: the BSDF is a pair of deltas (brdf and btdf return 0),
            // so the exact specular representation of the SmoothDielectric it equals: with the renormalization, the
            // flux-conserving one, which keeps its promise of energy per column (each column's total split between
            // the two ordinates around its image, as the renormalized lobe nearly is as sigma -> 0); the default
            // (pointwise) transmission broke it below smooth_sigma, by 4.5 at M = 8 (found by review).
            *this = InterfaceOperators(SmoothDielectric<Real>(interface.eta_above(), interface.eta_below()),
                                       ordinates, modes,
                                       renormalization == Renormalization::hemispherical_totals
                                           ? SpecularTransmission::flux_conserving
                                           : SpecularTransmission::pointwise);
            return;
        }
        if (interface.eta_above() > interface.eta_below()) {
            // Built the way up (denser medium below) and turned over (flipped()): a layer's bottom face, the turned
            // top, then equals top.flipped() bit for bit, which lets a solve reuse one face for both.
            *this = InterfaceOperators(RoughDielectric<Real>(interface.sigma(), interface.eta_below(),
                                                             interface.eta_above(), interface.shadowing()),
                                       ordinates, modes, rule, renormalization, totals_nodes);
            turn_over();
            return;
        }
        // Reciprocity halves the work (and makes the matrices reciprocal to the last bit):
        //   I^{r}(mu_m -> mu_n) = I^{r}(mu_n -> mu_m)  (r(i, o) = r(o, i), the reversed path has the same dphi),
        //   I^{t21}(mu_n -> mu_m) = (n_1 / n_2)^2 I^{t12}(mu_m -> mu_n)  (t_12(i, o) / n_2^2 = t_21(o, i) / n_1^2),
        // and the azimuthal rule of a pair depends on it symmetrically (same lobe width and breakpoints), so
        // the mirrored entries are exactly what a separate integration would give, up to rounding.
        // (tests/test_interface_operators.cpp checks the entries against the coefficient functions.)
        r12_ = FourierOperators<Real>(m, modes);
        r21_ = FourierOperators<Real>(m, modes);
        t12_ = FourierOperators<Real>(m, modes);
        t21_ = FourierOperators<Real>(m, modes);
        const Real ratio = (interface.eta_above() / interface.eta_below()) * (interface.eta_above() / interface.eta_below());
        std::vector<Real> c(static_cast<std::size_t>(modes));
        const auto weight = [&](int i) {
            return ordinates.weights[static_cast<std::size_t>(i)] * ordinates.nodes[static_cast<std::size_t>(i)];
        };
        // Shadowing::masking_only (G1 of the incident direction alone) is not reciprocal: no mirroring then.
        const bool reciprocal = interface.shadowing() != Shadowing::masking_only;
        if (!reciprocal) {  // every entry integrated (through coefficients(): the shadowing once per pair)
            for (int side = 0; side < 2; ++side)
                for (int lobe = 0; lobe < 2; ++lobe) {
                    FourierOperators<Real>& op = lobe == 0 ? (side == 0 ? r12_ : r21_) : (side == 0 ? t12_ : t21_);
                    for (int a = 0; a < m; ++a)
                        for (int b = 0; b < m; ++b) {
                            coefficients(side == 0 ? Incidence::from_above : Incidence::from_below, lobe == 1,
                                         ordinates.nodes[static_cast<std::size_t>(a)],
                                         ordinates.nodes[static_cast<std::size_t>(b)], c.data());
                            for (int k = 0; k < modes; ++k) op(k, b, a) = weight(a) * c[static_cast<std::size_t>(k)];
                        }
                }
            if (renormalization == Renormalization::hemispherical_totals) renormalize(ordinates, totals_nodes);
            return;
        }
        for (int a = 0; a < m; ++a) {
            const Real mu_a = ordinates.nodes[static_cast<std::size_t>(a)];
            for (int b = 0; b < m; ++b) {
                const Real mu_b = ordinates.nodes[static_cast<std::size_t>(b)];
                if (b >= a) {  // reflection: (b, a) and its mirror (a, b)
                    for (int side = 0; side < 2; ++side) {
                        coefficients(side == 0 ? Incidence::from_above : Incidence::from_below, false, mu_a, mu_b, c.data());
                        FourierOperators<Real>& r = side == 0 ? r12_ : r21_;
                        for (int k = 0; k < modes; ++k) {
                            r(k, b, a) = weight(a) * c[static_cast<std::size_t>(k)];
                            r(k, a, b) = weight(b) * c[static_cast<std::size_t>(k)];
                        }
                    }
                }
                // transmission from above mu_a -> below mu_b, and its reverse from below mu_b -> above mu_a
                coefficients(Incidence::from_above, true, mu_a, mu_b, c.data());
                for (int k = 0; k < modes; ++k) {
                    t12_(k, b, a) = weight(a) * c[static_cast<std::size_t>(k)];
                    t21_(k, a, b) = weight(b) * ratio * c[static_cast<std::size_t>(k)];
                }
            }
        }
        if (renormalization == Renormalization::hemispherical_totals) renormalize(ordinates, totals_nodes);
    }

    /// Smooth interface (sigma = 0): exact specular representation (see above). `transmission` chooses how
    /// the Snell-mapped transmission is put on the ordinates (default: pointwise); `points` is the local
    /// Lagrange window (0 = the default: 2 for flux_conserving, 4 for pointwise; at most M is used).
    /// Throws std::invalid_argument for modes < 1, an empty ordinate set or points < 0.
    InterfaceOperators(const SmoothDielectric<Real>& interface, const Quadrature<Real>& ordinates, int modes,
                       SpecularTransmission transmission = SpecularTransmission::pointwise, int points = 0)
        : modes_(detail::require_count("modes", modes, 1)),
          index_matched_(interface.eta_above() == interface.eta_below()), specular_(true) {
        detail::require_count("ordinates", static_cast<int>(ordinates.size()), 1);
        detail::require_count("points", points, 0);
        const int m = static_cast<int>(ordinates.size());
        if (index_matched_) {
            set_index_matched(m);
            return;
        }
        // Into the denser medium the Snell map compresses the hemisphere into the critical cone (splitting
        // hits every ordinate there); out of it the map expands (interpolation stays smooth).
        const bool denser_below = interface.eta_below() > interface.eta_above();
        const auto conserves = [&](int side) {  // side 0: T_12 (travelling down), 1: T_21
            if (transmission == SpecularTransmission::automatic) return (side == 0) == denser_below;
            return transmission == SpecularTransmission::flux_conserving;
        };
        r12_ = FourierOperators<Real>(m, modes);
        r21_ = FourierOperators<Real>(m, modes);
        t12_ = FourierOperators<Real>(m, modes);
        t21_ = FourierOperators<Real>(m, modes);
        const auto weight = [&](int i) {
            return ordinates.weights[static_cast<std::size_t>(i)] * ordinates.nodes[static_cast<std::size_t>(i)];
        };
        std::vector<Real> w(static_cast<std::size_t>(std::max(points, 4)));
        // Ordinates below the critical cosine on the denser side are totally reflected: no transmitted beam
        // lands there and none of their light crosses. Both constructions use only the ordinates that cross
        // (the last one at least): a beam split onto, or a field interpolated from, a totally reflected
        // ordinate couples light into directions that two lossless faces trap (a stack's thin or
        // non-scattering slab between smooth faces), where it accumulated without bound and leaked back out
        // (solve_stack created up to 1000 times the incident energy; tests/test_layer_inputs.cpp).
        // crossing(sign): the first ordinate whose light, arriving with cosine sign * mu, is transmitted.
        const auto crossing = [&](Real sign) {
            int i = 0;
            while (i < m - 1 && !(interface.transmitted_cosine(sign * ordinates.nodes[static_cast<std::size_t>(i)]) != 0))
                ++i;
            return i;
        };
        for (int j = 0; j < m; ++j) {
            const Real mu = ordinates.nodes[static_cast<std::size_t>(j)];
            const Real f12 = interface.reflectance(mu), f21 = interface.reflectance(-mu);
            for (int k = 0; k < modes; ++k) {
                r12_(k, j, j) = f12;
                r21_(k, j, j) = f21;
            }
            for (int side = 0; side < 2; ++side) {  // side 0: T_12 (light arriving from above), 1: T_21
                FourierOperators<Real>& t = side == 0 ? t12_ : t21_;
                const Real in_sign = side == 0 ? Real(1) : Real(-1);  // sign of wi.z for light from that side
                int first = 0;
                const bool conserve = conserves(side);
                // The ordinates that may be used: those of the transmitted medium (conserve) or of the incident
                // one (pointwise) that cross the interface (see `crossing` above).
                const int lowest = crossing(conserve ? -in_sign : in_sign);
                const int p = std::min(points > 0 ? points : (conserve ? 2 : 4), m - lowest);
                if (conserve) {
                    // Column j: the beam from ordinate j goes to mu_t = Snell(mu_j) with power 1 - F(mu_j);
                    // split it over the ordinates around mu_t with weights s (sum 1) so that the flux
                    // sum_n w_n mu_n T_{n,j} = w_j mu_j (1 - F(mu_j)) exactly.
                    const Real mu_t = std::fabs(interface.transmitted_cosine(in_sign * mu));
                    if (!(mu_t > 0)) continue;  // total internal reflection: nothing is transmitted
                    const Real x = std::fmin(std::fmax(mu_t, ordinates.nodes[static_cast<std::size_t>(lowest)]),
                                             ordinates.nodes.back());
                    first = detail::lagrange_weights(ordinates.nodes.data(), m, x, p, w.data(), lowest).first;
                    const Real power = interface.transmittance(in_sign * mu) * weight(j);
                    for (int a = 0; a < p; ++a)
                        for (int k = 0; k < modes; ++k) t(k, first + a, j) = power * w[static_cast<std::size_t>(a)] / weight(first + a);
                } else {
                    // Row j: the radiance arriving at ordinate j comes from mu_i = Snell^{-1}(mu_j) (the
                    // reversed ray), times (n_t/n_i)^2 (1 - F(mu_i)); interpolate the incident field there.
                    const Real mu_i = std::fabs(interface.transmitted_cosine(-in_sign * mu));
                    if (!(mu_i > 0)) continue;  // no incident direction reaches mu_j
                    const Real factor = interface.radiance_transmittance(in_sign * mu_i);
                    first = detail::lagrange_weights(ordinates.nodes.data(), m, mu_i, p, w.data(), lowest).first;
                    for (int a = 0; a < p; ++a)
                        for (int k = 0; k < modes; ++k) t(k, j, first + a) = factor * w[static_cast<std::size_t>(a)];
                }
            }
        }
    }

    /// An opaque Lambertian floor of albedo A under a medium (Boundary::lambertian): light arriving from above
    /// is reflected with radiance A / pi times its irradiance, in mode 0 only, (R12)_nm = 2 A w_m mu_m for
    /// every n (its flux 2 pi sum_n w_n mu_n R12_nm / (2 pi) = A w_m mu_m, since sum_n w_n mu_n = 1/2); nothing is
    /// transmitted; R21 = 0 (nothing arrives from below an opaque floor). Throws std::invalid_argument for A
    /// outside [0, 1], modes < 1 or an empty ordinate set.
    static InterfaceOperators lambertian_floor(Real albedo, const Quadrature<Real>& ordinates, int modes) {
        detail::require_closed("albedo", albedo, Real(0), Real(1));
        detail::require_count("ordinates", static_cast<int>(ordinates.size()), 1);
        InterfaceOperators ops(SmoothDielectric<Real>(Real(1), Real(1)), ordinates, modes);  // sizes; specular
        const int m = static_cast<int>(ordinates.size());
        ops.index_matched_ = false;
        ops.t12_ = FourierOperators<Real>(m, modes);
        ops.t21_ = FourierOperators<Real>(m, modes);
        ops.totals_above_.assign(ordinates.size(), HemisphericalTotals<Real>{albedo, Real(0)});
        ops.totals_below_.assign(ordinates.size(), HemisphericalTotals<Real>{Real(0), Real(0)});
        for (int j = 0; j < m; ++j) {
            const Real w = ordinates.weights[static_cast<std::size_t>(j)] * ordinates.nodes[static_cast<std::size_t>(j)];
            for (int n = 0; n < m; ++n) ops.r12_(0, n, j) = 2 * albedo * w;
        }
        return ops;
    }

    /// The operators of this interface turned upside down (its indices exchanged, as the bottom face of a layer whose
    /// top is this one): light arriving at it from above is light arriving here from below, mirrored in the surface,
    /// which a Gaussian microsurface cannot tell apart (microfacet.hpp); so R12 and R21, T12 and T21, and the totals
    /// of the two sides exchange. For a rough interface equal to building the turned interface's operators, bit for
    /// bit (the constructor builds every rough interface with the denser medium below, and turns it when needed);
    /// built from the other orientation they agree within 5e-14 (rounding of the totals' integrals; measured at
    /// sigma 0.3, n 1 | 1.4, M = 16, 32 modes). The cost of a copy.
    InterfaceOperators flipped() const {
        InterfaceOperators out = *this;
        out.turn_over();
        return out;
    }

    /// A rough interface's operators with another number of modes (the layer solver builds them for the modes a
    /// request's tolerance is expected to need, and for more when it needs them): its azimuthal integrals again, on
    /// the rule that resolves `modes` modes, and its renormalization from the totals held (they do not depend on the
    /// modes), so without the hemispherical integrals. `ordinates` must be those the operators were built on. Equal
    /// to building them afresh for `modes`, bit for bit (tests/test_interface_operators.cpp). (Operators built for
    /// fewer modes use a coarser azimuthal rule: their modes differ from those of a build for more by up to 2e-10 of
    /// an entry from 12 modes on, 2e-8 at 8, measured against 48 over sigma 0.05 to 3 at n 1 | 1.05 and 1 | 1.4,
    /// M = 24, at 24 points per panel; with the 12 points a tolerance takes, 8.3e-13 of a layer's largest output,
    /// tests/test_layer_prepared.cpp.) Throws std::invalid_argument for modes < 1, other ordinates, or a specular
    /// interface's operators.
    InterfaceOperators with_modes(const Quadrature<Real>& ordinates, int modes) const {
        detail::require_count("modes", modes, 1);
        if (specular_ || !rough_) detail::fail_invalid_argument("stratum: InterfaceOperators::with_modes: not a rough interface");
        if (static_cast<int>(ordinates.size()) != size())
            detail::fail_invalid_argument("stratum: InterfaceOperators::with_modes: ordinates of another size");
        InterfaceOperators out(*rough_, ordinates, modes, *rule_, Renormalization::none);
        if (!totals_above_.empty()) {
            out.totals_above_ = totals_above_;
            out.totals_below_ = totals_below_;
            out.apply_renormalization(ordinates);
        }
        return out;
    }

    int size() const noexcept { return r12_.size; }
    int modes() const noexcept { return modes_; }
    /// True for index matching (T = identity, R = 0).
    bool index_matched() const noexcept { return index_matched_; }
    /// True when the interface is specular (smooth or index-matched): its BSDF is a delta and the
    /// coefficient functions below return zeros; the operators are the exact representations above.
    bool specular() const noexcept { return specular_; }

    const FourierOperators<Real>& R12() const noexcept { return r12_; }
    const FourierOperators<Real>& T12() const noexcept { return t12_; }
    const FourierOperators<Real>& R21() const noexcept { return r21_; }
    const FourierOperators<Real>& T21() const noexcept { return t21_; }

    /// The exact hemispherical totals RoughDielectric::hemispherical_totals at each ordinate for light arriving from the
    /// given side (computed by Renormalization::hemispherical_totals; empty otherwise).
    const std::vector<HemisphericalTotals<Real>>& ordinate_totals(Incidence side) const noexcept {
        return side == Incidence::from_above ? totals_above_ : totals_below_;
    }

    /// I_k(mu_in, mu_out), k = 0..modes()-1, written to out[0..modes()-1], at any cosines in [0, 1]
    /// (absolute values; the sides are given by the function): reflection or transmission of light
    /// arriving from above (r12_, t12_coefficients) or below (r21_, t21_coefficients): the azimuthal Fourier
    /// coefficients at true angles, where R12() etc. are the matrices on the ordinates. Zeros for a specular interface.
    void r12_coefficients(Real mu_in, Real mu_out, Real* out) const noexcept { coefficients(Incidence::from_above, false, mu_in, mu_out, out); }
    void t12_coefficients(Real mu_in, Real mu_out, Real* out) const noexcept { coefficients(Incidence::from_above, true, mu_in, mu_out, out); }
    void r21_coefficients(Real mu_in, Real mu_out, Real* out) const noexcept { coefficients(Incidence::from_below, false, mu_in, mu_out, out); }
    void t21_coefficients(Real mu_in, Real mu_out, Real* out) const noexcept { coefficients(Incidence::from_below, true, mu_in, mu_out, out); }

    /// The same for a chosen side and lobe.
    void coefficients(Incidence side, bool transmission, Real mu_in, Real mu_out, Real* out) const noexcept {
        coefficients(side, transmission, mu_in, mu_out, out, modes_);
    }
    /// The first `modes` (1 <= modes <= modes()) coefficients only, from an azimuthal rule that resolves just
    /// those (fewer samples). Equal to the full call's within that rule's error: measured 2.3e-13 relative for
    /// transmission; for reflection inside the denser medium at sigma >= 1, where the rule of one mode has few
    /// panels, up to 2.6e-6 (1.7e-5 at sigma 3, n 1 | 1.05; found by review).
    void coefficients(Incidence side, bool transmission, Real mu_in, Real mu_out, Real* out, int modes) const noexcept {
        if (specular_) {
            for (int k = 0; k < modes; ++k) out[k] = Real(0);
            return;
        }
        const detail::RoughKernel<Real> kernel{&*rough_, side, transmission};
        azimuthal_coefficients(kernel.at(mu_in, mu_out), mu_in, mu_out, kernel.features(mu_in, mu_out), modes, out, *rule_);
    }

private:
    // Scales column m of each operator (all modes alike) so that its flux-weighted sum equals the
    // interface's hemispherical total for incidence mu_m (RoughDielectric::hemispherical_totals), blended continuously
    // with the specular column (see the constructor's comment) where the ordinates miss the lobe.
    void renormalize(const Quadrature<Real>& ordinates, int nodes) {
        totals_above_.clear();
        totals_below_.clear();
        for (const Real mu : ordinates.nodes) {
            totals_above_.push_back(rough_->hemispherical_totals(mu, nodes));
            totals_below_.push_back(rough_->hemispherical_totals(-mu, nodes));
        }
        apply_renormalization(ordinates);
    }

    // The scaling and blend of renormalize(), from the totals held.
    void apply_renormalization(const Quadrature<Real>& ordinates) {
        const int m_count = static_cast<int>(ordinates.size());
        const auto weight = [&](int i) {
            return ordinates.weights[static_cast<std::size_t>(i)] * ordinates.nodes[static_cast<std::size_t>(i)];
        };
        Real split[2];
        std::vector<Real> shape;
        for (int side = 0; side < 2; ++side) {
            FourierOperators<Real>& r = side == 0 ? r12_ : r21_;
            FourierOperators<Real>& t = side == 0 ? t12_ : t21_;
            const Real eta_i = side == 0 ? rough_->eta_above() : rough_->eta_below();
            const Real eta_o = side == 0 ? rough_->eta_below() : rough_->eta_above();
            for (int m = 0; m < m_count; ++m) {
                const Real mu = ordinates.nodes[static_cast<std::size_t>(m)];
                const HemisphericalTotals<Real> target = (side == 0 ? totals_above_ : totals_below_)[static_cast<std::size_t>(m)];
                for (int lobe = 0; lobe < 2; ++lobe) {
                    FourierOperators<Real>& op = lobe == 0 ? r : t;
                    const Real total = lobe == 0 ? target.reflectance : target.transmittance;
                    Real flux = 0;
                    for (int n = 0; n < m_count; ++n) flux += weight(n) * op(0, n, m);
                    flux /= weight(m);
                    // Blend, continuous in every parameter: with r = flux / total, the lobe rescaled to the
                    // total gets the share alpha = min(r, 1/r) and the specular column the rest; both carry
                    // the total, so the column's energy is exact, and a resolved lobe (r ~ 1) is kept as is.
                    const Real r_ratio = total > 0 ? flux / total : Real(0);
                    const Real lobe_scale = !(flux > 0) ? Real(0) : r_ratio >= 1 ? total / flux / r_ratio : Real(1);
                    const Real specular_share = !(total > 0) ? Real(0)
                                                : r_ratio >= 1 ? Real(1) - Real(1) / r_ratio : Real(1) - r_ratio;
                    for (int k = 0; k < modes_; ++k)
                        for (int n = 0; n < m_count; ++n) op(k, n, m) *= lobe_scale;
                    if (!(specular_share > 0)) continue;
                    // Specular column: image cosine (mirror, or Snell with eta_i sin_i = eta_o sin_o).
                    const Real e = eta_i / eta_o;
                    const Real image = lobe == 0 ? mu : std::sqrt(std::fmax(Real(0), 1 - e * e * (1 - mu) * (1 + mu)));
                    const Real x = std::fmin(std::fmax(image, ordinates.nodes.front()), ordinates.nodes.back());
                    const int first = detail::lagrange_weights(ordinates.nodes.data(), m_count, x, 2, split).first;
                    // The lobe's own azimuthal shape at its image, I_k / I_0 (a delta in phi would not decay
                    // with k and would defeat the adaptive mode count of the layer solver).
                    shape.resize(static_cast<std::size_t>(modes_));
                    coefficients(side == 0 ? Incidence::from_above : Incidence::from_below, lobe == 1, mu, image,
                                 shape.data());
                    const Real i0 = shape[0];
                    for (int a = 0; a < std::min(2, m_count); ++a)
                        for (int k = 0; k < modes_; ++k) {
                            const Real ratio = i0 > 0 ? shape[static_cast<std::size_t>(k)] / i0 : Real(k == 0);
                            op(k, first + a, m) += specular_share * total * weight(m) * split[a] / weight(first + a) * ratio;
                        }
                }
            }
        }
    }

    // flipped() in place: the indices exchanged, the sides' operators and totals swapped.
    void turn_over() {
        if (rough_) rough_.emplace(rough_->sigma(), rough_->eta_below(), rough_->eta_above(), rough_->shadowing());
        std::swap(r12_, r21_);
        std::swap(t12_, t21_);
        std::swap(totals_above_, totals_below_);
    }

    void set_index_matched(int m) {
        r12_ = FourierOperators<Real>(m, modes_);
        r21_ = FourierOperators<Real>(m, modes_);
        t12_ = FourierOperators<Real>::identity(m, modes_);
        t21_ = FourierOperators<Real>::identity(m, modes_);
    }

    std::optional<RoughDielectric<Real>> rough_;  // the rough interface; empty for a smooth one
    std::optional<AzimuthalQuadrature<Real>> rule_;  // a rough face's azimuthal rule (a smooth one needs none)
    int modes_;
    bool index_matched_;
    bool specular_;
    FourierOperators<Real> r12_, t12_, r21_, t21_;
    std::vector<HemisphericalTotals<Real>> totals_above_, totals_below_;  // per ordinate, when renormalized
};

}  // namespace stratum
