// tests/reference/mc_layer.hpp -- an independent photon Monte Carlo of a plane-parallel scattering layer between two
// dielectric boundaries (test-only code; not part of the library).
//
// It shares nothing with the solver but the Fresnel formula (stratum::fresnel_dielectric, tested on its own
// in test_fresnel.cpp): the microfacet normals, the refraction, the free paths and the Henyey-Greenstein
// (or Rayleigh) scattering are sampled here from their definitions.
//
// Geometry. Medium 1 above, the layer (index n2, optical thickness tau, single-scattering albedo Omega,
// Henyey-Greenstein asymmetry g) in the middle, medium 3 below. Directions are PROPAGATION directions in the
// local frame (z = macro normal pointing into medium 1). A photon arrives from above travelling along
// d0 = (sqrt(1 - mu0^2), 0, -mu0) and is followed until it is absorbed, lost, or leaves the layer.
//
// Boundaries. Index matched: crossed unchanged. Smooth: specular Fresnel reflection or Snell refraction.
// Rough: a Gaussian height field with RMS slope sigma (slopes p, q independent N(0, sigma^2); Beckmann with
// alpha = sqrt(2) sigma). A photon arriving with w = -d (pointing back to where it came from, w.z > 0 after
// mirroring the frame when it comes from below) hits facets with slope (p, q) in proportion to the slope
// density times the facet's projected area seen from w per unit macro area, (w.m) / (m.z) = w.z - w_t.(p, q)
// (m = (-p, -q, 1)/|.|), clipped at 0 (back-facing facets are not hit). This is the visible-normal
// distribution of Smith's model. It reflects with probability F(w.m) (exact dielectric Fresnel) and refracts
// otherwise; a reflected direction pointing into the facet's far side (o.z <= 0) or a refracted one pointing
// back (o.z >= 0) is LOST: one facet interaction and no further shadowing, which is exactly what the
// `Shadowing::masking_only` form of RoughDielectric describes.
//
// Sampling the visible slopes. Write the slope along w's horizontal direction as sigma x and the one across
// it as sigma y, x, y ~ N(0, 1) a priori. The hit density is prop. to phi(x) phi(y) (mu - s sigma x)_+ with
// mu = w.z, s = |w_t|; y stays N(0, 1). For x, rejection from the proposal prop. to
// phi(x) (mu + s sigma |x|) = mu phi(x) + s sigma |x| phi(x), a mixture of N(0, 1) (weight mu) and a signed
// Rayleigh variable (weight s sigma sqrt(2 / pi), since int |x| phi = sqrt(2 / pi)); accept with probability
// (mu - s sigma x)_+ / (mu + s sigma |x|) <= 1. Exact, and the acceptance rate is >= 1/2.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include <stratum/fresnel.hpp>

namespace mc_layer {

constexpr double pi = 3.141592653589793238462643383279502884;

struct V3 {
    double x, y, z;
};
inline V3 operator+(V3 a, V3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline V3 operator*(double s, V3 a) { return {s * a.x, s * a.y, s * a.z}; }
inline double dot(V3 a, V3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline V3 unit(V3 a) { return (1 / std::sqrt(dot(a, a))) * a; }

/// Uniform doubles from std::mt19937_64 with our own mapping (the std distributions differ between
/// standard libraries): 53 random bits, u in [0, 1).
class Rng {
public:
    explicit Rng(std::uint64_t seed) : engine_(seed) {}
    double uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
    double open_uniform() { return 1 - uniform(); }  // (0, 1]
    /// Standard normal by Box-Muller (one of the pair).
    double normal() { return std::sqrt(-2 * std::log(open_uniform())) * std::cos(2 * pi * uniform()); }

private:
    std::mt19937_64 engine_;
};

/// One boundary: matched (invisible), smooth (specular) or rough (Gaussian facets of RMS slope sigma).
struct Boundary {
    enum Kind { matched, smooth, rough } kind;
    double n_above, n_below, sigma;
    static Boundary index_matched(double n) { return {matched, n, n, 0}; }
    static Boundary specular(double n_above, double n_below) { return {smooth, n_above, n_below, 0}; }
    static Boundary gaussian(double sigma, double n_above, double n_below) { return {rough, n_above, n_below, sigma}; }
};

/// A unit vector orthogonal to the unit vector n, and n x that vector (an orthonormal frame around n).
inline void frame(V3 n, V3& t, V3& b) {
    if (std::fabs(n.z) < 0.9) t = unit(V3{-n.y, n.x, 0});
    else t = unit(V3{0, -n.z, n.y});
    b = {n.y * t.z - n.z * t.y, n.z * t.x - n.x * t.z, n.x * t.y - n.y * t.x};
}

/// Samples the facet normal hit by light arriving from w (w.z > 0, pointing away from the surface).
inline V3 visible_facet_normal(V3 w, double sigma, Rng& rng) {
    const double mu = w.z, s = std::sqrt(w.x * w.x + w.y * w.y);
    const V3 e_par = s > 0 ? V3{w.x / s, w.y / s, 0} : V3{1, 0, 0};
    const V3 e_perp{-e_par.y, e_par.x, 0};
    const double b = s * sigma;
    const double p_gauss = mu / (mu + b * std::sqrt(2 / pi));
    double x;
    for (;;) {
        if (rng.uniform() < p_gauss) {
            x = rng.normal();
        } else {
            x = std::sqrt(-2 * std::log(rng.open_uniform()));
            if (rng.uniform() < 0.5) x = -x;
        }
        const double hit = mu - b * x;
        if (hit > 0 && rng.uniform() * (mu + b * std::fabs(x)) < hit) break;
    }
    const double p_par = sigma * x, p_perp = sigma * rng.normal();
    return unit(V3{-p_par * e_par.x - p_perp * e_perp.x, -p_par * e_par.y - p_perp * e_perp.y, 1});
}

/// Scatters a photon travelling along d (d.z != 0) at boundary `bd`. Returns false if it is lost (sent
/// into the wrong hemisphere by a facet); otherwise d becomes the new propagation direction (d.z has the
/// sign of the side it now travels into: same sign as before = transmitted).
inline bool cross_boundary(const Boundary& bd, V3& d, Rng& rng) {
    if (bd.kind == Boundary::matched || bd.n_above == bd.n_below) return true;
    const bool from_below = d.z > 0;
    const double eta = from_below ? bd.n_above / bd.n_below : bd.n_below / bd.n_above;  // n_t / n_i
    V3 w{-d.x, -d.y, from_below ? d.z : -d.z};  // mirrored so that w.z > 0
    const V3 m = bd.kind == Boundary::smooth ? V3{0, 0, 1} : visible_facet_normal(w, bd.sigma, rng);
    const double c = dot(w, m);
    const double F = stratum::fresnel_dielectric(c, eta);
    V3 o;
    if (rng.uniform() < F) {
        o = (2 * c) * m + (-1) * w;
        if (!(o.z > 0)) return false;
    } else {
        const double sin2_t = (1 - c) * (1 + c) / (eta * eta);
        if (!(sin2_t < 1)) return false;  // unreachable: F = 1 there
        const double cos_t = std::sqrt(1 - sin2_t);
        o = unit((c / eta - cos_t) * m + (-1 / eta) * w);
        if (!(o.z < 0)) return false;
    }
    d = from_below ? V3{o.x, o.y, -o.z} : o;
    return true;
}

/// Henyey-Greenstein scattering of d (exact inversion of the CDF of the scattering cosine).
inline V3 scatter_hg(V3 d, double g, Rng& rng) {
    const double u = rng.uniform();
    double c;
    if (g == 0) {
        c = 1 - 2 * u;
    } else {
        const double q = (1 - g * g) / (1 - g + 2 * g * u);
        c = (1 + g * g - q * q) / (2 * g);
    }
    c = std::fmin(1.0, std::fmax(-1.0, c));
    const double s = std::sqrt((1 - c) * (1 + c)), phi = 2 * pi * rng.uniform();
    V3 t, b;
    frame(d, t, b);
    return unit((s * std::cos(phi)) * t + (s * std::sin(phi)) * b + c * d);
}

/// Rayleigh scattering of d: the cosine c has the density (3/8)(1 + c^2) on [-1, 1], whose CDF
/// (c^3 + 3 c + 4) / 8 = u is inverted by Cardano's formula for the one real root of c^3 + 3c + (4 - 8u) = 0.
inline V3 scatter_rayleigh(V3 d, Rng& rng) {
    const double q = 4 * rng.uniform() - 2;  // -(4 - 8u) / 2
    const double r = std::sqrt(q * q + 1);   // sqrt(q^2 + (p / 3)^3) with p = 3
    double c = std::cbrt(q + r) + std::cbrt(q - r);
    c = std::fmin(1.0, std::fmax(-1.0, c));
    const double s = std::sqrt((1 - c) * (1 + c)), phi = 2 * pi * rng.uniform();
    V3 t, b;
    frame(d, t, b);
    return unit((s * std::cos(phi)) * t + (s * std::sin(phi)) * b + c * d);
}

struct Layer {
    Boundary top, bottom;
    double albedo, g, tau;  // tau may be +inf
    bool rayleigh = false;  // Rayleigh phase function instead of Henyey-Greenstein (g unused)
};

/// Counts of photon fates, and histograms of the exit directions over (mu, |dphi|) bins: mu bins equal in
/// mu^2 (equal projected solid angle), |dphi| bins equal in [0, pi]; dphi is the azimuth of the exit
/// direction relative to the incident propagation direction (specular reflection at dphi = 0).
struct Tally {
    int mu_bins, phi_bins;
    std::int64_t photons = 0, surface = 0, surface_lost = 0, subsurface = 0, transmitted = 0, absorbed = 0,
                 lost = 0, runaway = 0;
    std::vector<std::int64_t> surface_hist, subsurface_hist, transmitted_hist;
    Tally(int nm, int np)
        : mu_bins(nm), phi_bins(np), surface_hist(static_cast<std::size_t>(nm * np)),
          subsurface_hist(surface_hist.size()), transmitted_hist(surface_hist.size()) {}
    std::size_t bin(V3 d) const {
        int i = static_cast<int>(d.z * d.z * mu_bins);
        if (i >= mu_bins) i = mu_bins - 1;
        const double a = std::fabs(std::atan2(d.y, d.x));
        int j = static_cast<int>(a / pi * phi_bins);
        if (j >= phi_bins) j = phi_bins - 1;
        return static_cast<std::size_t>(i * phi_bins + j);
    }
    /// A fraction of the photons and its Monte Carlo standard error (binomial).
    double fraction(std::int64_t count) const { return static_cast<double>(count) / static_cast<double>(photons); }
    double std_error(std::int64_t count) const {
        const double p = fraction(count);
        return std::sqrt(std::fmax(p * (1 - p), 1.0 / static_cast<double>(photons)) / static_cast<double>(photons));
    }
};

/// Traces `photons` photons arriving from above with cosine mu0 (0 < mu0 <= 1).
inline Tally trace(const Layer& layer, double mu0, std::int64_t photons, std::uint64_t seed, int mu_bins = 4,
                   int phi_bins = 3) {
    Rng rng(seed);
    Tally t(mu_bins, phi_bins);
    t.photons = photons;
    const V3 d0{std::sqrt((1 - mu0) * (1 + mu0)), 0, -mu0};
    const double tau = layer.tau;
    for (std::int64_t n = 0; n < photons; ++n) {
        V3 d = d0;
        if (!cross_boundary(layer.top, d, rng)) {
            ++t.surface_lost;
            continue;
        }
        if (d.z > 0) {
            ++t.surface;
            ++t.surface_hist[t.bin(d)];
            continue;
        }
        double z = 0;  // optical depth coordinate: 0 at the top, -tau at the bottom
        for (int events = 0;; ++events) {
            if (events > 10000000) {
                ++t.runaway;
                break;
            }
            const double l = -std::log(rng.open_uniform());
            const double to_boundary = d.z < 0 ? (z + tau) / -d.z : -z / d.z;
            if (l >= to_boundary) {  // reaches a boundary (never the bottom of a semi-infinite slab)
                const bool at_top = d.z > 0;
                z = at_top ? 0 : -tau;
                if (!cross_boundary(at_top ? layer.top : layer.bottom, d, rng)) {
                    ++t.lost;
                    break;
                }
                if (at_top && d.z > 0) {
                    ++t.subsurface;
                    ++t.subsurface_hist[t.bin(d)];
                    break;
                }
                if (!at_top && d.z < 0) {
                    ++t.transmitted;
                    ++t.transmitted_hist[t.bin(d)];
                    break;
                }
                continue;  // reflected back into the layer
            }
            z += l * d.z;
            if (rng.uniform() >= layer.albedo) {
                ++t.absorbed;
                break;
            }
            d = layer.rayleigh ? scatter_rayleigh(d, rng) : scatter_hg(d, layer.g, rng);
        }
    }
    return t;
}

}  // namespace mc_layer
