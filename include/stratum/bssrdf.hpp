// stratum/bssrdf.hpp -- the dipole (dipole.hpp) as a renderer's BSSRDF: a separable S = (1 - F(cos theta_o)) S_p(r)
// S_w(wi) per colour channel, the probe-ray importance sampling of the point of entry over channels and projection
// axes with its combined density, and the recipe that turns an artist's diffuse colour into the medium.
//
// Conventions (docs/physics.md section 8): directions and points in the local frame of the point of exit po
// (z = its normal, x and y tangents); eta = n_medium / n_outside. The separable form (as pbrt-v3 and v4 use it):
//   S(po, wo; pi, wi) = (1 - F(|wo.z|)) S_p(|pi - po|) S_w(wi),  S_p = R_d(r) of each channel,
//   S_w(w) = (1 - F(|w.z|)) / (pi (1 - F_h)),  F_h = 2 int_0^1 F(mu) mu dmu (seen from outside),
// normalized so that int S_w cos dw = 1 over the hemisphere (Jensen et al. 2001 write 1/pi instead of
// 1/(pi (1 - F_h)); R_d then loses the light the Fresnel factors reflect twice over).
//
// Recipe for textures (Hery, "Implementing a skin BSSRDF", section 2): an artist paints the diffuse colour R_d and
// the diffuse mean free path l_d per channel; per texel and channel, alpha' = AlphaPrimeTable(eta)(R_d) (a table
// built once per eta; or alpha_prime_from_reflectance, exact) and Dipole::from_albedo(alpha', l_d, eta), so that
// the dipole's total diffuse reflectance is R_d and sigma_tr = 1 / l_d. DipoleBSSRDF::from_reflectance does this
// for one set of channels.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <utility>

#include "detail/config.hpp"
#include "detail/math.hpp"
#include "detail/validate.hpp"
#include "dipole.hpp"
#include "fresnel.hpp"
#include "vec3.hpp"

namespace stratum {

/// A probe ray's sample (DipoleBSSRDF::sample_probe): the renderer intersects the segment
/// origin + s axis, s in [-half_length, half_length] (local frame of po, origin relative to po), with the surface;
/// each hit pi is a point of entry with density DipoleBSSRDF::pdf(pi - po, normal at pi). axis 0, 1, 2 = x, y, z.
template <class Real = double>
struct ProbeSample {
    Vec3<Real> origin{}, axis{};
    Real half_length = 0;
    int channel = 0;
    bool valid() const noexcept { return half_length > 0; }
};

/// The dipole of N channels (e.g. RGB) as a separable BSSRDF with probe sampling (see the header comment).
/// Evaluation and sampling are noexcept and allocation-free; construction validates.
template <class Real, std::size_t N>
class DipoleBSSRDF {
public:
    /// The channels' dipoles, all of the same eta (throws std::invalid_argument otherwise, or if a channel has no
    /// absorption: its radius distribution does not exist). `probe_quantile` in (0, 1): the probe's half length is
    /// the radius below which that share of the most spread channel's samples fall (0.999 as in pbrt-v3).
    explicit DipoleBSSRDF(const std::array<Dipole<Real>, N>& channels, Real probe_quantile = Real(0.999))
        : channels_(channels) {
        static_assert(N >= 1, "at least one channel");
        const Real eta = channels_[0].eta();
        for (const Dipole<Real>& d : channels_) {
            if (d.eta() != eta) detail::throw_out_of_range("DipoleBSSRDF channel eta", d.eta(), "the first channel's eta");
            detail::require_positive("DipoleBSSRDF channel sigma_tr", d.sigma_tr());
        }
        detail::require_open("probe_quantile", probe_quantile, Real(0), Real(1));
        Real smallest = std::numeric_limits<Real>::infinity();
        for (const Dipole<Real>& d : channels_) smallest = std::fmin(smallest, d.sigma_tr());
        // sample_radius(q) sigma_tr is the quantile in u = sigma_tr r, the same for every channel
        half_length_ = channels_[0].sample_radius(probe_quantile) * channels_[0].sigma_tr() / smallest;
        eta_ = eta;
        sw_norm_ = Real(1) / (detail::pi_v<Real> * (1 - fresnel_hemispherical_reflectance(eta)));
    }

    /// Hery's recipe per channel: diffuse colour Rd in [0, 1) and diffuse mean free path ld > 0 (length).
    static DipoleBSSRDF from_reflectance(const std::array<Real, N>& Rd, const std::array<Real, N>& ld, Real eta,
                                         DiffuseFresnel model = DiffuseFresnel::jensen_fit) {
        return DipoleBSSRDF(make(Rd, ld, eta, model, std::make_index_sequence<N>{}));
    }

    const std::array<Dipole<Real>, N>& channels() const noexcept { return channels_; }
    Real eta() const noexcept { return eta_; }
    /// The probe segment's half length (length units).
    Real probe_half_length() const noexcept { return half_length_; }

    /// S_p(r) = R_d(r) per channel (1/length^2).
    void Sp(Real r, Real* out) const noexcept {
        for (std::size_t c = 0; c < N; ++c) out[c] = channels_[c].Rd(r);
    }
    /// 1 - F(|w.z|): the Fresnel transmittance at the point of exit towards wo (the factor before S_p).
    Real exit_transmittance(Vec3<Real> wo) const noexcept { return 1 - fresnel_dielectric(std::fabs(wo.z), eta_); }
    /// S_w(wi) = (1 - F(|wi.z|)) / (pi (1 - F_h)) (1/sr): int S_w |wi.z| dwi = 1 over the hemisphere.
    Real Sw(Vec3<Real> wi) const noexcept { return (1 - fresnel_dielectric(std::fabs(wi.z), eta_)) * sw_norm_; }

    /// Samples a probe with three uniforms in [0, 1): the axis by u_axis (z, the normal, with probability 1/2; x and
    /// y 1/4 each), the channel uniformly by u_axis's place within the axis's share, the radius from the channel's
    /// sigma_tr^2 r e^{-sigma_tr r} by u1 (Dipole::sample_radius) and the azimuth around the axis by u2. Uniforms
    /// outside [0, 1), NaN included, are clamped into it (detail::clamp_uniform; a NaN u_axis indexed the channels at
    /// INT_MIN, found by a review sweep).
    ProbeSample<Real> sample_probe(Real u_axis, Real u1, Real u2) const noexcept {
        ProbeSample<Real> p;
        int axis = 2;
        Real u = detail::clamp_uniform(u_axis);
        if (u < Real(0.5)) {
            u = 2 * u;
        } else if (u < Real(0.75)) {
            axis = 0;
            u = 4 * (u - Real(0.5));
        } else {
            axis = 1;
            u = 4 * (u - Real(0.75));
        }
        const int channel = std::min(static_cast<int>(u * Real(N)), static_cast<int>(N) - 1);
        const Real r = channels_[static_cast<std::size_t>(channel)].sample_radius(u1);
        const Real phi = 2 * detail::pi_v<Real> * detail::clamp_uniform(u2);
        const Real a = r * std::cos(phi), b = r * std::sin(phi);
        // The disk's point in the plane perpendicular to the axis: (a, b) on the other two axes, in order.
        p.origin = axis == 2 ? Vec3<Real>{a, b, 0} : (axis == 0 ? Vec3<Real>{0, a, b} : Vec3<Real>{b, 0, a});
        p.axis = axis == 2 ? Vec3<Real>{0, 0, 1} : (axis == 0 ? Vec3<Real>{1, 0, 0} : Vec3<Real>{0, 1, 0});
        p.half_length = half_length_;
        p.channel = channel;
        return p;
    }

    /// The density (per unit area) of a probe hit at d = pi - po with unit normal n at pi (both in po's local
    /// frame), over every axis and channel: sum_axis P_axis |n . axis| sum_c (1/N) p_c(r_axis), with r_axis the
    /// distance from po perpendicular to the axis and p_c(r) = sigma_tr^2 e^{-sigma_tr r} / (2 pi) the channel's
    /// radial density per unit area.
    Real pdf(Vec3<Real> d, Vec3<Real> n) const noexcept {
        // sqrt(a^2 + b^2), by hypot where the squares underflow or overflow (float distances below ~1e-19, where
        // the profile of a sigma_tr beyond 1e19 still lives).
        const auto length = [](Real a, Real b) noexcept {
            const Real q = a * a + b * b;
            return q >= std::numeric_limits<Real>::min() && q <= std::numeric_limits<Real>::max() ? std::sqrt(q) : std::hypot(a, b);
        };
        const Real r[3] = {length(d.y, d.z), length(d.z, d.x), length(d.x, d.y)};
        const Real cos_axis[3] = {std::fabs(n.x), std::fabs(n.y), std::fabs(n.z)};
        const Real prob[3] = {Real(0.25), Real(0.25), Real(0.5)};
        Real total = 0;
        for (int a = 0; a < 3; ++a) {
            Real sum = 0;
            for (const Dipole<Real>& ch : channels_) {
                const Real s = ch.sigma_tr(), u = s * r[a];
                // s^2 e^{-u} = (s e^{-u/2})^2: s^2 alone overflows for sigma_tr beyond sqrt(max) (1.8e19 in float),
                // and 0 x inf was NaN on an axis the normal is perpendicular to (found by the renderer sweep).
                const Real root = s * std::exp(-u / 2);
                sum += u < std::numeric_limits<Real>::infinity() ? root * root : Real(0);
            }
            if (cos_axis[a] > 0) total += prob[a] * cos_axis[a] * sum / (Real(N) * 2 * detail::pi_v<Real>);
        }
        return total;
    }

private:
    template <std::size_t... I>
    static std::array<Dipole<Real>, N> make(const std::array<Real, N>& Rd, const std::array<Real, N>& ld, Real eta,
                                            DiffuseFresnel model, std::index_sequence<I...>) {
        return {Dipole<Real>::from_reflectance(Rd[I], ld[I], eta, model)...};
    }

    std::array<Dipole<Real>, N> channels_;
    Real eta_ = 1, half_length_ = 0, sw_norm_ = 0;
};

}  // namespace stratum
