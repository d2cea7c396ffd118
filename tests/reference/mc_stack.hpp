// tests/reference/mc_stack.hpp -- an independent photon Monte Carlo of a plane-parallel STACK of homogeneous
// slabs separated by smooth (specular) dielectric faces, lit from above by a collimated beam (test-only code;
// not part of the library).
//
// It shares nothing with the solver but the Fresnel formula (stratum::fresnel_dielectric, tested on its own in
// test_fresnel.cpp): Snell refraction, the free paths and the Henyey-Greenstein scattering are sampled here
// from their definitions.
//
// Geometry. Media are numbered 0..L+1 from the top: medium 0 (index n_above) above the top face, slab j
// (j = 0..L-1, index eta[j], optical thickness tau[j], single-scattering albedo albedo[j], Henyey-Greenstein
// asymmetry g[j]) in the middle, medium L+1 (index n_below) below the bottom face. Face k (k = 0..L) lies
// between medium k (above it) and medium k+1 (below it). Every face is a smooth interface: a photon reaching
// it reflects specularly with the exact unpolarized Fresnel probability F and otherwise refracts by Snell's
// law (equal indices: F = 0, it crosses unchanged; total internal reflection: F = 1). tau[j] may be 0 (the
// photon crosses the slab without an event) or +inf (nothing gets below it). With Stack::floor_albedo >= 0 the
// bottom face is a Lambertian floor instead (see there).
//
// State. The faces are infinite planes and the tallies are fluxes integrated over all exit directions and
// positions, so a photon's state is just (slab j, optical depth t below the slab's top face, c). c is the
// cosine of the propagation direction with the DOWNWARD normal (c > 0: moving down). Both Snell's law
// (n sin is conserved) and the scattering (new cosine from the old one, the scattering cosine and a uniform
// azimuth, by the spherical law of cosines) need only c, so no horizontal position or azimuth is carried.
// The incident photon travels along (sqrt(1 - mu0^2), 0, -mu0) (z up), i.e. c = mu0 in medium 0.
//
// Tallies (fractions of the incident photons, each with its binomial standard error):
//   r_specular   reflected by the top face at the first encounter (never entered the stack);
//   r_direct     entered the stack and left through the top face without ever scattering;
//   r_scattered  left through the top face after at least one scattering;
//   t_direct / t_scattered  the same through the bottom face;
//   absorbed     absorbed at a scattering event (probability 1 - albedo[j] at each event);
//   runaway      still inside after `max_events` free paths (counted in nothing else; 0 in practice unless
//                a thick conservative stack makes paths extremely long).
// R = r_specular + r_direct + r_scattered and T = t_direct + t_scattered; R + T + absorbed + runaway = 1.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <stratum/fresnel.hpp>

namespace mc_stack {

constexpr double two_pi = 6.283185307179586476925286766559005768;

struct Stack {
    double n_above = 1, n_below = 1;
    std::vector<double> eta, tau, albedo, g;  // one entry per slab, top to bottom
    /// >= 0: a Lambertian floor of this albedo instead of the bottom face (n_below unused). A photon reaching it
    /// is absorbed with probability 1 - floor_albedo, otherwise sent back up with a cosine-weighted direction
    /// (|c| = sqrt(u)), and counts as scattered.
    double floor_albedo = -1;
};

struct Result {
    std::uint64_t photons = 0;
    double r_specular = 0, r_direct = 0, r_scattered = 0, t_direct = 0, t_scattered = 0, absorbed = 0, runaway = 0;
    // Binomial standard errors sqrt(p (1 - p) / N); p (1 - p) is floored at 1 / N (see detail::se).
    double se_r = 0, se_t = 0;  // of the totals R and T
    double se_r_specular = 0, se_r_direct = 0, se_r_scattered = 0, se_t_direct = 0, se_t_scattered = 0,
           se_absorbed = 0;
    double R() const { return r_specular + r_direct + r_scattered; }
    double T() const { return t_direct + t_scattered; }
};

namespace detail {

/// Uniform doubles in [0, 1) from the top 53 bits of std::mt19937_64 (our own mapping: the std
/// distributions differ between standard libraries, which would break determinism across platforms).
class Uniform {
public:
    explicit Uniform(std::uint64_t seed) : engine_(seed) {}
    double operator()() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }

private:
    std::mt19937_64 engine_;
};

/// Binomial standard error of a fraction p of n trials, sqrt(max(p (1 - p), 1 / n) / n): a tally of 0 or n
/// gets the one-event bound 1 / n rather than a misleading 0.
inline double se(double p, double n) { return std::sqrt(std::fmax(p * (1 - p), 1 / n) / n); }

/// Henyey-Greenstein scattering cosine by inverting its CDF:
///   P(cos <= c) = (1 - g^2) / (2g) [ (1 + g^2 - 2 g c)^(-1/2) - (1 + g)^(-1) ],
/// so with u uniform, s = (1 - g^2) / (1 - g + 2 g u), cos = (1 + g^2 - s^2) / (2 g). g = 0: uniform.
inline double hg_cosine(double g, double u) {
    if (g == 0) return 2 * u - 1;
    const double s = (1 - g * g) / (1 - g + 2 * g * u);
    const double c = (1 + g * g - s * s) / (2 * g);
    return c < -1 ? -1 : (c > 1 ? 1 : c);
}

/// Direction cosine after a scattering by angle acos(ct) at azimuth phi around the old direction
/// (spherical law of cosines: only the cosine with the normal is needed).
inline double rotate_cosine(double c, double ct, double phi) {
    const double s2 = (1 - c) * (1 + c) * (1 - ct) * (1 + ct);
    const double cn = c * ct + std::sqrt(s2 > 0 ? s2 : 0) * std::cos(phi);
    return cn < -1 ? -1 : (cn > 1 ? 1 : cn);
}

/// A photon with direction cosine c (c != 0; sign = direction of travel) reaches a smooth face going from
/// index n_i into index n_t. Returns true if it is transmitted (c becomes the refracted cosine, same sign);
/// false if reflected (c changes sign).
inline bool cross_face(double n_i, double n_t, double& c, double u) {
    if (n_i == n_t) return true;
    const double a = std::fabs(c);
    const double ratio = n_t / n_i;
    const double F = stratum::fresnel_dielectric(a, ratio);
    if (u < F) {
        c = -c;
        return false;
    }
    const double r = n_i / n_t;
    const double sin2_t = (1 - a) * (1 + a) * r * r;
    if (!(sin2_t < 1)) {  // unreachable: F = 1 under total internal reflection
        c = -c;
        return false;
    }
    const double ct = std::sqrt(1 - sin2_t);
    c = c > 0 ? ct : -ct;
    return true;
}

inline void check(bool ok, const std::string& what) {
    if (!ok) throw std::invalid_argument("mc_stack::simulate: " + what);
}

}  // namespace detail

/// Traces `photons` photons (deterministic for a given seed). mu0 in (0, 1]. max_events caps the free
/// paths per photon (see `runaway`).
inline Result simulate(const Stack& s, double mu0, std::uint64_t photons, std::uint64_t seed,
                       std::uint64_t max_events = 100000000) {
    const std::size_t L = s.eta.size();
    detail::check(L >= 1, "need at least one slab");
    detail::check(s.tau.size() == L && s.albedo.size() == L && s.g.size() == L, "eta, tau, albedo, g sizes differ");
    detail::check(s.n_above > 0 && s.n_below > 0 && std::isfinite(s.n_above) && std::isfinite(s.n_below),
                  "outer indices must be positive and finite");
    for (std::size_t j = 0; j < L; ++j) {
        detail::check(s.eta[j] > 0 && std::isfinite(s.eta[j]), "eta must be positive and finite");
        detail::check(s.tau[j] >= 0, "tau must be >= 0 (+inf allowed)");
        detail::check(s.albedo[j] >= 0 && s.albedo[j] <= 1, "albedo must be in [0, 1]");
        detail::check(s.g[j] > -1 && s.g[j] < 1, "g must be in (-1, 1)");
    }
    detail::check(s.floor_albedo <= 1, "floor_albedo must be <= 1");
    detail::check(mu0 > 0 && mu0 <= 1, "mu0 must be in (0, 1]");
    detail::check(photons > 0, "photons must be > 0");

    // Indices of media 0..L+1.
    std::vector<double> n(L + 2);
    n[0] = s.n_above;
    for (std::size_t j = 0; j < L; ++j) n[j + 1] = s.eta[j];
    n[L + 1] = s.n_below;

    detail::Uniform u(seed);
    std::uint64_t c_spec = 0, c_rdir = 0, c_rsca = 0, c_tdir = 0, c_tsca = 0, c_abs = 0, c_run = 0;
    const double inf = std::numeric_limits<double>::infinity();

    for (std::uint64_t p = 0; p < photons; ++p) {
        double c = mu0;
        if (!detail::cross_face(n[0], n[1], c, u())) {
            ++c_spec;
            continue;
        }
        std::size_t j = 0;  // current slab
        double t = 0;       // optical depth below the top face of slab j
        bool scattered = false;
        std::uint64_t events = 0;
        for (;;) {
            if (++events > max_events) {
                ++c_run;
                break;
            }
            const double tau = s.tau[j];
            // Optical path to the face ahead (c == 0: never reaches one).
            const double to_face = c > 0 ? (tau - t) / c : (c < 0 ? t / -c : inf);
            const double l = -std::log(1 - u());  // 1 - u in (0, 1]
            if (l < to_face) {                     // interaction inside slab j
                t += l * c;
                if (!(u() < s.albedo[j])) {
                    ++c_abs;
                    break;
                }
                scattered = true;
                const double ct = detail::hg_cosine(s.g[j], u());
                c = detail::rotate_cosine(c, ct, two_pi * u());
                continue;
            }
            // Reaches the face ahead: face j + 1 going down (into medium j + 2), face j going up (into medium j).
            if (c > 0) {
                if (j + 1 == L && s.floor_albedo >= 0) {  // the floor
                    if (!(u() < s.floor_albedo)) {
                        ++c_abs;
                        break;
                    }
                    scattered = true;
                    c = -std::sqrt(1 - u());  // cosine-weighted, moving up (1 - u in (0, 1]: never on the horizon)
                    t = tau;
                } else if (detail::cross_face(n[j + 1], n[j + 2], c, u())) {
                    if (j + 1 == L) {
                        ++(scattered ? c_tsca : c_tdir);
                        break;
                    }
                    ++j;
                    t = 0;
                } else {
                    t = tau;
                }
            } else {
                if (detail::cross_face(n[j + 1], n[j], c, u())) {
                    if (j == 0) {
                        ++(scattered ? c_rsca : c_rdir);
                        break;
                    }
                    --j;
                    t = s.tau[j];
                } else {
                    t = 0;
                }
            }
        }
    }

    Result r;
    const double N = static_cast<double>(photons);
    r.photons = photons;
    r.r_specular = static_cast<double>(c_spec) / N;
    r.r_direct = static_cast<double>(c_rdir) / N;
    r.r_scattered = static_cast<double>(c_rsca) / N;
    r.t_direct = static_cast<double>(c_tdir) / N;
    r.t_scattered = static_cast<double>(c_tsca) / N;
    r.absorbed = static_cast<double>(c_abs) / N;
    r.runaway = static_cast<double>(c_run) / N;
    r.se_r = detail::se(r.R(), N);
    r.se_t = detail::se(r.T(), N);
    r.se_r_specular = detail::se(r.r_specular, N);
    r.se_r_direct = detail::se(r.r_direct, N);
    r.se_r_scattered = detail::se(r.r_scattered, N);
    r.se_t_direct = detail::se(r.t_direct, N);
    r.se_t_scattered = detail::se(r.t_scattered, N);
    r.se_absorbed = detail::se(r.absorbed, N);
    return r;
}

}  // namespace mc_stack
