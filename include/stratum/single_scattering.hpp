// stratum/single_scattering.hpp -- the single-scattering term of a BSSRDF (Jensen et al. 2001, as in
// Hery, "Implementing a skin BSSRDF", section 1.1), as a pure function of the geometric inputs.
//
// Geometry and conventions. Local frame with z the surface normal pointing OUT of the medium (into the
// medium the light comes from). Inside the medium two refracted rays meet at the scattering point x_s:
//   wi_t: unit vector from x_s back along the refracted incident light, towards where it entered (z > 0);
//   wo_t: unit vector from x_s along the refracted outgoing ray towards x_o, where it leaves (z > 0).
// Both point away from x_s (pbrt's convention); the scattering angle is between the propagation
// directions, -wi_t and wo_t:  cos_theta = -dot(wi_t, wo_t), so g > 0 favours forward scattering.
// eta = n_medium / n_outside, as everywhere in stratum. Lengths in one unit, sigma_s, sigma_t in 1/unit.
//
// The approximation (Jensen 2001, section 2.3). A renderer samples x_s at distance s_o' along wo_t and then
// traces from x_s to the light along the UNREFRACTED light direction (no refraction on the way in); that
// segment has length s_i. For a locally flat boundary the point's depth is s_i cos_i and the refracted path
// is longer by 1 / cos_i':
//   s_i' = s_i cos_i / cos_i',  sin_i = eta sin_i'  (Snell; cos_i' = wi_t.z, cos_i the outside cosine),
// with eta > 1 making s_i' < s_i. The segment is still traced in the wrong direction and ends at a different
// entry point; curvature and internal reflection are ignored.
//
// The terms. With F = F_t(entry) F_t(exit) (product of the Fresnel transmittances) and p the phase function:
//   integrand(s_o') = sigma_s F p(cos_theta) e^{-sigma_t s_i'} e^{-sigma_t s_o'}        [1/length]
// is the single-scattered outgoing radiance per unit length along wo_t, per unit incident radiance, so that
//   L_o^(1) = L_i int_0^inf integrand(s_o') ds_o'          (exact under the approximation above).
// Sampling s_o' with pdf sigma_t e^{-sigma_t s} (sample_distance / pdf_distance) gives the unbiased estimate
//   estimate = integrand / pdf = (sigma_s / sigma_t) F p e^{-sigma_t s_i'}.
// For a flat boundary s_i' = G s_o' with G = |wo_t.z| / |wi_t.z|, and the integral has the closed form
//   plane_parallel = sigma_s F p / sigma_tc,   sigma_tc = sigma_t (1 + G),
// the classic single-scattering reflection (omega F p mu_i' / (mu_i' + mu_o')). Jensen's and Hery's published
// term is that closed form multiplied by the attenuation of the sampled path,
//   published_term = sigma_s F p / sigma_tc e^{-sigma_t s_i'} e^{-sigma_t s_o'}   (term()),
// provided for comparison with their code. Note (tests/test_single_scattering.cpp): averaging the published
// term over s_o' drawn with pdf sigma_t e^{-sigma_t s}, as the usual recipe has it (docs/physics.md section 8), gives the
// flat-boundary answer divided by (2 + G), not the answer; estimate() is the unbiased form of that recipe.
#pragma once

#include <cmath>
#include <limits>

#include "detail/math.hpp"
#include "detail/validate.hpp"
#include "henyey_greenstein.hpp"
#include "vec3.hpp"

namespace stratum {

/// Snell's correction of the light's in-medium distance: s_i' = s_i cos_i / cos_i', where cos_i in [0, 1] is
/// the cosine of the UNREFRACTED light direction to the normal and cos_i' = sqrt(1 - (1 - cos_i^2) / eta^2)
/// that of the refracted one (eta = n_medium / n_outside). For eta < 1 beyond the critical angle no light
/// enters: 0. Degenerate input (s_i <= 0, cos_i <= 0) gives 0.
template <class Real>
Real refracted_distance(Real s_i, Real cos_i, Real eta) noexcept {
    if (!(s_i > 0) || !(cos_i > 0)) return Real(0);
    const Real c = std::fmin(cos_i, Real(1));
    const Real cos_t2 = 1 - (1 - c) * (1 + c) / (eta * eta);
    if (!(cos_t2 > 0)) return Real(0);
    return s_i * c / std::sqrt(cos_t2);
}

/// The single-scattering term for one homogeneous medium with a Henyey-Greenstein phase function.
template <class Real = double>
class SingleScattering {
public:
    /// sigma_s in [0, sigma_t], sigma_t > 0 (1/length, finite), g in (-1, 1), eta = n_medium / n_outside in
    /// [1e-4, 1e4] (a refractive index ratio, as elsewhere in the library: eta = 1e200 was accepted, and eta^2
    /// overflowed into a distance of 0 at normal incidence; found by review).
    /// Throws std::invalid_argument naming the bad value.
    SingleScattering(Real sigma_s, Real sigma_t, Real g, Real eta)
        : sigma_t_(detail::require_positive("sigma_t", sigma_t)),
          sigma_s_(detail::require_closed("sigma_s", sigma_s, Real(0), sigma_t)),
          eta_(detail::require_refractive_index("eta", eta)),
          phase_(g) {}

    Real sigma_s() const noexcept { return sigma_s_; }
    Real sigma_t() const noexcept { return sigma_t_; }
    Real eta() const noexcept { return eta_; }
    const HenyeyGreenstein<Real>& phase() const noexcept { return phase_; }

    /// s_i' from the unrefracted distance s_i and the refracted direction wi_t (z > 0): the outside
    /// cosine follows from Snell, cos_i = sqrt(1 - eta^2 (1 - cos_i'^2)); 0 if wi_t lies outside the
    /// cone that light from outside can reach (eta > 1) or points into the medium.
    Real refracted_in_distance(Real s_i, const Vec3<Real>& wi_t) const noexcept {
        const Real c_t = wi_t.z;
        if (!(c_t > 0) || !(s_i > 0)) return Real(0);
        const Real c = std::fmin(c_t, Real(1));
        const Real cos_i2 = 1 - eta_ * eta_ * (1 - c) * (1 + c);
        if (!(cos_i2 > 0)) return Real(0);
        return s_i * std::sqrt(cos_i2) / c;
    }

    /// sigma_s F p(-wi_t . wo_t) e^{-sigma_t s_i'} e^{-sigma_t s_o'} (1/length): the outgoing radiance per unit
    /// length along wo_t per unit incident radiance, s_i' = refracted_in_distance(s_i, wi_t).
    /// 0 for degenerate geometry (either direction with z <= 0).
    Real integrand(const Vec3<Real>& wi_t, const Vec3<Real>& wo_t, Real s_i, Real s_o_prime,
                   Real fresnel_transmittance) const noexcept {
        if (!(wi_t.z > 0) || !(wo_t.z > 0)) return Real(0);
        const Real si = refracted_in_distance(s_i, wi_t);
        return sigma_s_ * fresnel_transmittance * phase_.eval(-dot(wi_t, wo_t)) *
               std::exp(-sigma_t_ * (si + std::fmax(s_o_prime, Real(0))));
    }

    /// The unbiased one-sample estimate of L_o / L_i for s_o' drawn with sample_distance:
    /// integrand / pdf_distance = (sigma_s / sigma_t) F p e^{-sigma_t s_i'} (dimensionless).
    Real estimate(const Vec3<Real>& wi_t, const Vec3<Real>& wo_t, Real s_i, Real fresnel_transmittance) const noexcept {
        if (!(wi_t.z > 0) || !(wo_t.z > 0)) return Real(0);
        const Real si = refracted_in_distance(s_i, wi_t);
        return sigma_s_ / sigma_t_ * fresnel_transmittance * phase_.eval(-dot(wi_t, wo_t)) * std::exp(-sigma_t_ * si);
    }

    /// sigma_tc = sigma_t (1 + G), G = |wo_t.z| / |wi_t.z| (Jensen's combined extinction; flat boundary); +inf
    /// where wi_t.z = 0, the limit of grazing incidence (where plane_parallel is 0), wo_t on the horizon too (it
    /// was 0 / 0 = NaN there; found by review).
    Real sigma_tc(const Vec3<Real>& wi_t, const Vec3<Real>& wo_t) const noexcept {
        const Real i = std::fabs(wi_t.z);
        if (!(i > 0)) return std::numeric_limits<Real>::infinity();
        return sigma_t_ * (1 + std::fabs(wo_t.z) / i);
    }

    /// The flat-boundary closed form of L_o / L_i = int integrand ds_o' = sigma_s F p / sigma_tc.
    Real plane_parallel(const Vec3<Real>& wi_t, const Vec3<Real>& wo_t, Real fresnel_transmittance) const noexcept {
        if (!(wi_t.z > 0) || !(wo_t.z > 0)) return Real(0);
        return sigma_s_ * fresnel_transmittance * phase_.eval(-dot(wi_t, wo_t)) / sigma_tc(wi_t, wo_t);
    }

    /// The published term (Jensen 2001; Hery 1.1): sigma_s F p / sigma_tc e^{-sigma_t s_i'} e^{-sigma_t s_o'}.
    /// See the header comment for what it is and is not.
    Real term(const Vec3<Real>& wi_t, const Vec3<Real>& wo_t, Real s_i, Real s_o_prime,
              Real fresnel_transmittance) const noexcept {
        if (!(wi_t.z > 0) || !(wo_t.z > 0)) return Real(0);
        const Real si = refracted_in_distance(s_i, wi_t);
        return plane_parallel(wi_t, wo_t, fresnel_transmittance) *
               std::exp(-sigma_t_ * (si + std::fmax(s_o_prime, Real(0))));
    }

    /// s_o' with pdf sigma_t e^{-sigma_t s}: s = -log(1 - xi) / sigma_t, xi clamped to [0, 1 - eps/2]
    /// (finite for xi = 1; 0 for xi <= 0 or NaN).
    Real sample_distance(Real xi) const noexcept {
        return -std::log1p(-detail::clamp_uniform(xi)) / sigma_t_;
    }

    /// sigma_t e^{-sigma_t s} for s >= 0, else 0.
    Real pdf_distance(Real s) const noexcept {
        if (!(s >= 0)) return Real(0);
        return sigma_t_ * std::exp(-sigma_t_ * s);
    }

private:
    Real sigma_t_, sigma_s_, eta_;
    HenyeyGreenstein<Real> phase_;
};

}  // namespace stratum
