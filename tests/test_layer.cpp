// The layer solver (layer.hpp): independent references, conservation laws, the request shortcuts and the
// hard cases (docs/physics.md section 6). The photon Monte Carlo comparison is in test_layer_monte_carlo.cpp.
#include <doctest/doctest.h>

#include <stratum/layer.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "test_util.hpp"

using stratum::Boundary;
using stratum::LayerOptions;
using stratum::LayerOutput;
using stratum::LayerRequest;
using stratum::RoughDielectric;
using stratum::Shadowing;
using stratum::Slab;
using stratum::SmoothDielectric;
using stratum::Vec3;
using stratum::solve_layer;
using stratum::solve_stack;

namespace {


LayerOptions with_ordinates(int m, int modes = 0, bool delta_m = true) {
    LayerOptions o;
    o.ordinates = m;
    o.modes = modes;
    o.delta_m = delta_m;
    return o;
}

// Chandrasekhar's H function for isotropic scattering, by fixed-point iteration of
//   1/H(mu) = sqrt(1 - w) + (w/2) int_0^1 mu' H(mu') / (mu + mu') dmu'
// on a 400-point half-range Gauss rule (docs/physics.md section 7). Independent of the solver.
struct ChandrasekharH {
    double w;
    std::vector<double> x, wt, h;
    explicit ChandrasekharH(double albedo) : w(albedo) {
        const auto q = stratum::gauss_legendre_half<double>(400);
        x = q.nodes;
        wt = q.weights;
        h.assign(x.size(), 1.0);
        for (int it = 0; it < 2000; ++it) {
            double change = 0;
            std::vector<double> next(x.size());
            for (std::size_t i = 0; i < x.size(); ++i) next[i] = eval_with(h, x[i]);
            for (std::size_t i = 0; i < x.size(); ++i) change = std::fmax(change, std::fabs(next[i] - h[i]));
            h = next;
            if (change < 1e-15) break;
        }
    }
    double eval_with(const std::vector<double>& hh, double mu) const {
        double s = 0;
        for (std::size_t j = 0; j < x.size(); ++j) s += wt[j] * x[j] * hh[j] / (mu + x[j]);
        return 1 / (std::sqrt(1 - w) + w / 2 * s);
    }
    double operator()(double mu) const { return eval_with(h, mu); }
};

Vec3<double> direction(double mu, double phi) { return stratum::spherical_direction(mu, phi); }

}  // namespace

TEST_CASE("semi-infinite isotropic slab: plane albedo is 1 - sqrt(1 - w) H(mu0) (Chandrasekhar)") {
    // Black (index-matched) boundaries; at the ordinates the solver is exact up to the discretization error of
    // the discrete-ordinate method, which docs/physics.md section 7 gives as ~4e-5 at 16 ordinates.
    for (double w : {0.5, 0.9, 0.99}) {
        const ChandrasekharH H(w);
        const auto q = stratum::gauss_legendre_half<double>(16);
        const auto layer = solve_layer(Slab<double>(w, 0.0, std::numeric_limits<double>::infinity()),
                                       Boundary<double>::index_matched(), Boundary<double>::index_matched(),
                                       with_ordinates(16, 1));
        double worst = 0;
        for (std::size_t i = 0; i < q.size(); ++i) {
            const double mu = q.nodes[i];
            worst = std::fmax(worst, std::fabs(layer.reflectance(mu).subsurface - (1 - std::sqrt(1 - w) * H(mu))));
        }
        MESSAGE("w = " << w << ": max |albedo - (1 - sqrt(1-w) H)| over the 16 ordinates = " << worst);
        CHECK(worst < 1e-4);
        // Between ordinates the incident beam is spread over the four nearest ordinates by Lagrange weights
        // (layer.hpp): measured error at mu0 = 0.5 and 1 below 2e-4.
        for (double mu : {0.5, 1.0})
            CHECK(std::fabs(layer.reflectance(mu).subsurface - (1 - std::sqrt(1 - w) * H(mu))) < 2e-4);
    }
}

TEST_CASE("the error against Chandrasekhar's H falls as the number of ordinates grows") {
    const double w = 0.9;
    const ChandrasekharH H(w);
    double previous = 1;
    for (int m : {4, 8, 16, 32}) {
        const auto q = stratum::gauss_legendre_half<double>(m);
        const auto layer = solve_layer(Slab<double>(w, 0.0, std::numeric_limits<double>::infinity()),
                                       Boundary<double>::index_matched(), Boundary<double>::index_matched(),
                                       with_ordinates(m, 1));
        double worst = 0;
        for (std::size_t i = 0; i < q.size(); ++i)
            worst = std::fmax(worst, std::fabs(layer.reflectance(q.nodes[i]).subsurface - (1 - std::sqrt(1 - w) * H(q.nodes[i]))));
        MESSAGE("M = " << m << ": max error " << worst);
        CHECK(worst < previous);
        previous = worst;
    }
    CHECK(previous < 1e-5);
}

TEST_CASE("a non-absorbing slab between smooth or index-matched boundaries conserves energy") {
    // R (surface + subsurface) + T = 1 exactly for Omega = 1: every component of the discrete system is
    // lossless. Rounding over ~100 operations on O(1) numbers: allow 1e-12.
    for (double g : {0.0, 0.8}) {
        for (int m : {4, 16}) {
            const Slab<double> slab(1.0, g, 2.0);
            const auto smooth = solve_layer(slab, SmoothDielectric<double>(1.0, 1.4), SmoothDielectric<double>(1.4, 1.0),
                                            with_ordinates(m));
            const auto matched = solve_layer(slab, Boundary<double>::index_matched(), Boundary<double>::index_matched(),
                                             with_ordinates(m));
            for (double mu : {1.0, 0.7, 0.3, 0.05}) {
                CHECK(std::fabs(smooth.reflectance(mu).total() + smooth.transmittance(mu) - 1) < 1e-12);
                CHECK(std::fabs(matched.reflectance(mu).total() + matched.transmittance(mu) - 1) < 1e-12);
            }
        }
    }
}

TEST_CASE("albedo exactly 1 is exact, and 1 - Omega -> 0 converges to it monotonically") {
    // docs/physics.md section 6: a plain eigen-solve is off by ~0.2 at Omega = 1; Stam's 0.999999 costs 1e-6.
    for (double g : {0.0, 0.8}) {
        double previous = -1;
        for (double om : {1e-6, 1e-9, 1e-12, 0.0}) {
            const auto layer = solve_layer(Slab<double>::from_one_minus_albedo(om, g, 2.0),
                                           Boundary<double>::index_matched(), Boundary<double>::index_matched(),
                                           with_ordinates(16));
            const double total = layer.reflectance(0.6).total() + layer.transmittance(0.6);
            CHECK(total > previous);
            CHECK(total <= 1 + 1e-12);
            previous = total;
        }
        CHECK(std::fabs(previous - 1) <= 1e-9);
    }
}

TEST_CASE("two stacked slabs with an index-matched boundary between them equal one slab") {
    // Adding two slabs of tau 0.7 and 1.3 must give the slab of tau 2 (exact identity of the method).
    const RoughDielectric<double> top(0.3, 1.0, 1.4), bottom(0.3, 1.4, 1.0);
    const auto one = solve_layer(Slab<double>(0.9, 0.8, 2.0), top, bottom, with_ordinates(8));
    const auto two = solve_stack<double>(top, {Slab<double>(0.9, 0.8, 0.7), Slab<double>(0.9, 0.8, 1.3)},
                                         {Boundary<double>::index_matched(1.4)}, bottom, with_ordinates(8));
    for (double mu : {1.0, 0.5, 0.2}) {
        CHECK(std::fabs(one.reflectance(mu).subsurface - two.reflectance(mu).subsurface) < 1e-10);
        CHECK(std::fabs(one.transmittance(mu) - two.transmittance(mu)) < 1e-10);
    }
    const Vec3<double> wi = direction(0.8, 0.3), wo = direction(0.4, 2.0), wt = direction(-0.6, 1.0);
    CHECK(std::fabs(one.brdf(wi, wo) - two.brdf(wi, wo)) < 1e-10);
    CHECK(std::fabs(one.btdf(wi, wt) - two.btdf(wi, wt)) < 1e-10);
}

TEST_CASE("between smooth faces, slabs stacked with index-matched faces keep the unscattered beam apart, as one slab does") {
    // Three slabs of the same medium (tau 0.2 + 0.3 + 0.5) between Fresnel faces equal one slab of tau 1. The
    // beam used to stay in the stack's discrete field: direct_transmittance was 0 and the BTDF held the beam as a
    // truncated Fourier series around the forward direction (17.6, 69.8 and 300.8 at M = 16, 32, 64 for two
    // slabs of tau 0.5, where the scattered BTDF is 0.6).
    const SmoothDielectric<double> top(1.0, 1.4), bottom(1.4, 1.0);
    const Boundary<double> matched = Boundary<double>::index_matched(1.4);
    for (const int m : {8, 16}) {
        const auto one = solve_layer(Slab<double>(0.9, 0.8, 1.0), top, bottom, with_ordinates(m));
        const auto three = solve_stack<double>(
            top, {Slab<double>(0.9, 0.8, 0.2), Slab<double>(0.9, 0.8, 0.3), Slab<double>(0.9, 0.8, 0.5)}, {matched, matched},
            bottom, with_ordinates(m));
        for (double mu : {1.0, 0.5, 0.2}) {
            INFO("M " << m << " mu " << mu);
            CHECK(one.direct_transmittance(mu) > 0.05);
            CHECK(std::fabs(one.direct_transmittance(mu) - three.direct_transmittance(mu)) < 1e-15);
            CHECK(std::fabs(one.direct_reflectance(mu) - three.direct_reflectance(mu)) < 1e-15);
            CHECK(std::fabs(one.forward_peak_transmittance(mu) - three.forward_peak_transmittance(mu)) < 1e-15);
            CHECK(std::fabs(one.transmittance(mu) - three.transmittance(mu)) < 1e-10);
            CHECK(std::fabs(one.reflectance(mu).subsurface - three.reflectance(mu).subsurface) < 1e-10);
        }
        const Vec3<double> normal = direction(1.0, 0.0), forward = direction(-1.0, 0.0), oblique = direction(-0.8, 1.0);
        CHECK(one.btdf(normal, forward) < 1);  // scattered light only
        CHECK(std::fabs(one.btdf(normal, forward) - three.btdf(normal, forward)) < 1e-10);
        CHECK(std::fabs(one.btdf(normal, oblique) - three.btdf(normal, oblique)) < 1e-10);
    }
}

TEST_CASE("a stack with a rough interior interface stays within [0, 1] and loses energy only to absorption") {
    const RoughDielectric<double> top(0.3, 1.0, 1.4), inner(0.2, 1.4, 1.33), bottom(0.3, 1.33, 1.0);
    const auto stack = solve_stack<double>(top, {Slab<double>(0.95, 0.8, 0.5), Slab<double>(0.99, 0.7, 3.0)}, {inner},
                                           bottom, with_ordinates(8));
    for (double mu : {1.0, 0.5, 0.1}) {
        const double r = stack.reflectance(mu).total(), t = stack.transmittance(mu);
        CHECK(r > 0);
        CHECK(t > 0);
        CHECK(r + t < 1);
    }
}

TEST_CASE("the ambient term between specular faces: the subsurface BRDF integrated over incidence, plus the bounce") {
    // A uniform sky of unit radiance: the subsurface radiance towards wo is the integral of subsurface_brdf(wi, wo)
    // |wi.z| over incidence (its mode 0, from fourier_coefficients at 200 Gauss cosines, each incidence solved at its
    // own angle) plus the unscattered bounce and the forward peak's share (direct_ and forward_peak_reflectance at
    // wo.z: deltas of the BRDF at the mirror direction). Measured relative differences: at most 1.08e-5 at M = 16
    // and 1.5e-10 at M = 32. Read from the ordinates' field, as before, the ambient term was 2.6% off at M = 16,
    // mu 0.1, and at albedo 0, where it is the bounce alone (closed form below), 26% (found by review).
    const Boundary<double> top = SmoothDielectric<double>(1.0, 1.4), bottom = SmoothDielectric<double>(1.4, 1.0);
    const stratum::Quadrature<double> g = stratum::gauss_legendre_half<double>(200);
    for (const int m : {16, 32}) {
        LayerOptions o;
        o.ordinates = m;
        const auto layer = solve_layer(Slab<double>(0.9, 0.5, 1.0), top, bottom, o);
        for (const double mu : {0.05, 0.1, 0.3, 0.7, 1.0}) {
            const std::vector<double> a = layer.fourier_coefficients(LayerOutput::subsurface_reflection, g.nodes, {mu});
            double integral = 0;
            for (std::size_t i = 0; i < g.size(); ++i)
                integral += g.weights[i] * g.nodes[i] * 2 * stratum_test::pi * a[i * static_cast<std::size_t>(layer.modes())] / mu;
            const double expected = integral + layer.direct_reflectance(mu) + layer.forward_peak_reflectance(mu);
            const double ambient = layer.ambient(direction(mu, 0.4));
            INFO("M " << m << ", mu " << mu << ": " << ambient << " against " << expected);
            CHECK(std::fabs(ambient - expected) <= (m == 16 ? 1.5e-5 : 1e-9) * expected);
        }
    }
    // albedo 0: the bounce, T12(mu) d^2 r23 T21 / (1 - r21 r23 d^2), d = e^{-tau / mu'} at the Snell cosine mu'
    LayerOptions o;
    o.ordinates = 16;
    const auto empty = solve_layer(Slab<double>(0.0, 0.5, 1.0), top, bottom, o);
    const SmoothDielectric<double> in(1.0, 1.4), out(1.4, 1.0);
    for (const double mu : {0.05, 0.1, 0.3, 1.0}) {
        const double mu_t = std::sqrt(1 - (1 - mu * mu) / (1.4 * 1.4)), d = std::exp(-1.0 / mu_t);
        const double r = in.reflectance(mu), r23 = out.reflectance(mu_t), r21 = in.reflectance(-mu_t);
        const double bounce = (1 - r) * d * d * r23 * (1 - r21) / (1 - r21 * r23 * d * d);
        CHECK(empty.ambient(direction(mu, 1.0)) == doctest::Approx(bounce).epsilon(1e-13));
    }
}

TEST_CASE("the subsurface BRDF is reciprocal within the discretization error") {
    // r_s(wi, wo) = r_s(wo, wi) holds for the exact solution. The discrete one differs by the azimuthal and
    // ordinate discretization and the renormalization of the operators to the exact hemispherical totals
    // (which is not reciprocal); measured max relative asymmetry at 16 ordinates 4.3e-3 (bound 1e-2).
    const auto layer = solve_layer(Slab<double>::from_transparency(0.9, 0.8, 0.5), RoughDielectric<double>(0.3, 1.0, 1.4),
                                   RoughDielectric<double>(0.3, 1.4, 1.0), with_ordinates(16));
    double worst = 0;
    for (double mi : {0.9, 0.6, 0.3})
        for (double mo : {0.95, 0.5, 0.2})
            for (double dphi : {0.0, 1.0, 2.5}) {
                const Vec3<double> wi = direction(mi, 0.0), wo = direction(mo, dphi);
                const double a = layer.subsurface_brdf(wi, wo), b = layer.subsurface_brdf(wo, wi);
                worst = std::fmax(worst, std::fabs(a - b) / std::fmax(a, b));
            }
    MESSAGE("max relative reciprocity error of r_s at M = 16: " << worst);
    CHECK(worst < 1e-2);
}

TEST_CASE("requests: each shortcut agrees with the full solution") {
    const auto slab = Slab<double>::from_transparency(0.9, 0.8, 0.5);
    const RoughDielectric<double> top(0.3, 1.0, 1.4), bottom(0.3, 1.4, 1.0);
    const auto options = with_ordinates(8);
    const auto full = solve_layer(slab, top, bottom, options);
    const Vec3<double> wi = direction(0.7, 0.0), wo = direction(0.5, 2.0), wt = direction(-0.8, 1.0);

    SUBCASE("reflection only: same numbers, no transmission") {
        LayerRequest<double> r;
        r.outputs = LayerOutput::surface_reflection | LayerOutput::subsurface_reflection;
        const auto layer = solve_layer(slab, top, bottom, options, r);
        CHECK(layer.brdf(wi, wo) == full.brdf(wi, wo));
        CHECK(layer.reflectance(0.7).subsurface == full.reflectance(0.7).subsurface);
        CHECK(layer.btdf(wi, wt) == 0.0);
    }
    SUBCASE("surface only: no solve at all") {
        LayerRequest<double> r;
        r.outputs = LayerOutput::surface_reflection;
        const auto layer = solve_layer(slab, top, bottom, options, r);
        CHECK(layer.modes() == 0);
        CHECK(layer.brdf(wi, wo) == top.brdf(wi, wo));
    }
    SUBCASE("ambient only: mode 0 alone gives the same ambient term") {
        LayerRequest<double> r;
        r.outputs = LayerOutput::ambient;
        const auto layer = solve_layer(slab, top, bottom, options, r);
        CHECK(layer.modes() == 1);
        CHECK(std::fabs(layer.ambient(wo) - full.ambient(wo)) <= 1e-15 * full.ambient(wo));
    }
    SUBCASE("fluxes only: mode 0 alone, without being told, gives the same reflectance and transmittance") {
        // Fluxes are mode-0 quantities (the azimuthal integral of a Fourier series keeps its k = 0 term). The
        // operators of a 1-mode solve come from an azimuthal rule built for mode 0 alone, so the values agree
        // with the full solve's to that rule's error, not bitwise (interface_operators.hpp: <= 1e-12; here ~1e-15).
        const SmoothDielectric<double> smooth_top(1.0, 1.4), smooth_bottom(1.4, 1.0);
        const std::pair<Boundary<double>, Boundary<double>> faces[] = {{top, bottom}, {smooth_top, smooth_bottom}};
        for (const auto& pair : faces) {
            const Boundary<double>& upper = pair.first;  // (not a structured binding: INFO captures it, C++17)
            const Boundary<double>& lower = pair.second;
            const auto everything = solve_layer(slab, upper, lower, options);
            LayerRequest<double> r;
            r.outputs = LayerOutput::reflectance | LayerOutput::transmittance;
            const auto layer = solve_layer(slab, upper, lower, options, r);
            CHECK(layer.modes() == 1);
            CHECK(everything.modes() == 16);
            for (double mu : {1.0, 0.7, 0.3, 0.05}) {
                INFO("rough " << upper.rough() << ", mu " << mu);
                const double rs = everything.reflectance(mu).subsurface, t = everything.transmittance(mu);
                CHECK(rs > 0.01);
                CHECK(t > 0.01);
                CHECK(std::fabs(layer.reflectance(mu).subsurface - rs) <= 1e-14 * rs);
                CHECK(std::fabs(layer.transmittance(mu) - t) <= 1e-14 * t);
                CHECK(layer.direct_transmittance(mu) == everything.direct_transmittance(mu));
                CHECK(layer.direct_reflectance(mu) == everything.direct_reflectance(mu));
            }
            CHECK(layer.brdf(wi, wo) == 0.0);  // neither the surface nor the subsurface reflection was requested
            CHECK(layer.btdf(wi, wt) == 0.0);
            // One flux alone: the other is not computed.
            r.outputs = LayerOutput::transmittance;
            const auto transmitted = solve_layer(slab, upper, lower, options, r);
            CHECK(transmitted.modes() == 1);
            CHECK(transmitted.reflectance(0.7).subsurface == 0.0);
            CHECK(transmitted.transmittance(0.7) == layer.transmittance(0.7));
        }
    }
    SUBCASE("precomputed incidences give the same values as on-the-fly evaluation") {
        LayerRequest<double> r;
        r.incidence = {0.7};
        const auto layer = solve_layer(slab, top, bottom, options, r);
        CHECK(std::fabs(layer.brdf(wi, wo) - full.brdf(wi, wo)) <= 1e-15 * full.brdf(wi, wo));
        CHECK(std::fabs(layer.btdf(wi, wt) - full.btdf(wi, wt)) <= 1e-15 * full.btdf(wi, wt));
        CHECK(layer.reflectance(0.7).surface == full.reflectance(0.7).surface);  // cached, the same integral
        CHECK(std::fabs(layer.reflectance(0.7).subsurface - full.reflectance(0.7).subsurface) <=
              1e-15 * full.reflectance(0.7).subsurface);
        CHECK(std::fabs(layer.transmittance(0.7) - full.transmittance(0.7)) <= 1e-15 * full.transmittance(0.7));
    }
    SUBCASE("a tolerance stops the mode loop early and stays within the tolerance") {
        for (double tol : {1e-2, 1e-3, 1e-5}) {
            LayerRequest<double> r;
            r.tolerance = tol;
            const auto layer = solve_layer(slab, top, bottom, with_ordinates(16), r);
            const auto reference = solve_layer(slab, top, bottom, with_ordinates(16));
            double worst = 0, peak = 0;
            for (double mo : {0.95, 0.6, 0.2})
                for (double dphi : {0.0, 0.5, 1.5, 3.0}) {
                    const Vec3<double> o = direction(mo, dphi), t = direction(-mo, dphi);
                    worst = std::fmax(worst, std::fabs(layer.subsurface_brdf(wi, o) - reference.subsurface_brdf(wi, o)));
                    worst = std::fmax(worst, std::fabs(layer.btdf(wi, t) - reference.btdf(wi, t)));
                    peak = std::fmax(peak, std::fmax(reference.subsurface_brdf(wi, o), reference.btdf(wi, t)));
                }
            MESSAGE("tolerance " << tol << ": " << layer.modes() << " of " << reference.modes()
                                 << " modes, max error relative to the peak " << worst / peak);
            CHECK(layer.modes() < reference.modes());
            CHECK(worst <= tol * peak);
        }
    }
    SUBCASE("the layer's operators alone with a tolerance: the modes the BRDF and BTDF they carry need") {
        // The mode cut measured the BRDF's and BTDF's fields only, and with the operators alone it measured nothing:
        // every mode was negligible and the solve stopped after 3 (of 16 at 8 ordinates, 24 at 12, where mode 3's
        // entries are 0.34 of mode 0's; found by review). The operators now count as both outputs.
        for (const double tol : {1e-2, 1e-3}) {
            LayerRequest<double> r;
            r.tolerance = tol;
            r.outputs = LayerOutput::operators;
            const auto cut = solve_layer(slab, top, bottom, with_ordinates(12), r);
            r.outputs = LayerOutput::operators | LayerOutput::subsurface_reflection | LayerOutput::transmission;
            const auto angular = solve_layer(slab, top, bottom, with_ordinates(12), r);
            INFO("tolerance " << tol);
            CHECK(cut.modes() > 3);
            CHECK(cut.modes() == angular.modes());
        }
    }
    SUBCASE("a thick slab is solved as semi-infinite when transmission is not requested") {
        // The diffuse field decays as e^{-lambda_min tau} (lambda_min ~ 0.3 here), so at tau = 200 the slab is
        // semi-infinite to 1e-9: the shortcut must give exactly the tau = infinity solution and differ from the
        // full finite-tau solution by less than the tolerance.
        LayerRequest<double> r;
        r.outputs = LayerOutput::subsurface_reflection;
        r.tolerance = 1e-9;
        r.max_modes = 4;
        LayerRequest<double> f;
        f.max_modes = 4;
        f.outputs = LayerOutput::subsurface_reflection;
        const auto cut = solve_layer(Slab<double>(0.9, 0.8, 200.0), top, bottom, options, r);
        const auto finite = solve_layer(Slab<double>(0.9, 0.8, 200.0), top, bottom, options, f);
        const auto infinite = solve_layer(Slab<double>(0.9, 0.8, std::numeric_limits<double>::infinity()), top, bottom,
                                          options, f);
        CHECK(cut.reflectance(0.7).subsurface == infinite.reflectance(0.7).subsurface);
        CHECK(std::fabs(cut.reflectance(0.7).subsurface - finite.reflectance(0.7).subsurface) < 1e-9);
        // At tau = 20 the diffuse light still reaches the bottom (e^{-0.3 * 20} ~ 2e-3): no shortcut.
        const auto thin = solve_layer(Slab<double>(0.9, 0.8, 20.0), top, bottom, options, r);
        CHECK(thin.reflectance(0.7).subsurface != infinite.reflectance(0.7).subsurface);
        // Nor at tau = 25 (e^{-0.3 * 25} = 5.5e-4): within the tolerance of the finite solve (found by mutation
        // testing: a shortcut judged by e^{-tau}, 1.4e-11 here, took it and missed by 1.2e-7), and a weakly absorbing
        // slab (albedo 0.99, tau 10) at tolerance 1e-3 within 1e-3 (2.6e-9 measured; that shortcut 7.8e-3 off).
        const auto finite25 = solve_layer(Slab<double>(0.9, 0.8, 25.0), top, bottom, options, f);
        CHECK(std::fabs(solve_layer(Slab<double>(0.9, 0.8, 25.0), top, bottom, options, r).reflectance(0.7).subsurface -
                        finite25.reflectance(0.7).subsurface) <= 1e-9);
        LayerRequest<double> loose;
        loose.outputs = LayerOutput::subsurface_reflection | LayerOutput::reflectance;
        loose.tolerance = 1e-3;
        LayerRequest<double> whole;
        whole.outputs = loose.outputs;
        const Slab<double> weak(0.99, 0.0, 10.0);
        CHECK(std::fabs(solve_layer(weak, top, bottom, options, loose).reflectance(0.7).subsurface -
                        solve_layer(weak, top, bottom, options, whole).reflectance(0.7).subsurface) <= 1e-3);
    }
}

TEST_CASE("optical thickness from 0 to infinity: finite, bounded, and continuous at both ends") {
    const RoughDielectric<double> top(0.3, 1.0, 1.4), bottom(0.3, 1.4, 1.0);
    std::vector<double> albedo;
    for (double tau : {0.0, 1e-10, 1e-3, 1.0, 30.0, 1e3, 1e6, std::numeric_limits<double>::infinity()}) {
        const auto layer = solve_layer(Slab<double>(0.9, 0.8, tau), top, bottom, with_ordinates(8));
        const double a = layer.reflectance(0.6).total(), t = layer.transmittance(0.6);
        CHECK(std::isfinite(a));
        CHECK(std::isfinite(t));
        CHECK(a >= 0);
        CHECK(t >= 0);
        CHECK(a + t <= 1);
        albedo.push_back(a);
    }
    CHECK(std::fabs(albedo[0] - albedo[1]) < 1e-9);   // tau = 0 vs 1e-10
    CHECK(std::fabs(albedo[5] - albedo[7]) < 1e-12);  // 1e3 vs infinity
    CHECK(std::fabs(albedo[6] - albedo[7]) < 1e-12);  // 1e6 vs infinity
}

TEST_CASE("a slab of zero thickness between a rough top and an index-matched bottom is the top interface alone") {
    // Nothing comes back from below: the subsurface term is exactly 0, and the transmittance is the top's
    // hemispherical transmittance (the entering flux is rescaled to its tabulated exact value).
    const RoughDielectric<double> top(0.3, 1.0, 1.4);
    const auto layer = solve_layer(Slab<double>(0.9, 0.8, 0.0), top, Boundary<double>::index_matched(1.4), with_ordinates(16));
    for (double mu : {1.0, 0.6, 0.2}) {
        CHECK(layer.reflectance(mu).subsurface == 0.0);
        MESSAGE("mu = " << mu << ": layer T " << layer.transmittance(mu) << " vs interface T " << top.hemispherical_transmittance(mu));
        CHECK(std::fabs(layer.transmittance(mu) - top.hemispherical_transmittance(mu)) < 1e-6);  // table: <= 1e-7 here
    }
}

namespace {
// int f(wo) |wo.z| dwo over a hemisphere, by a 24-point half-range Gauss rule in |mu| and a 48-point periodic
// trapezoid rule in phi (spectrally accurate for the smooth truncated Fourier series in phi).
template <class F>
double hemisphere_integral(F f, bool upper) {
    const auto q = stratum::gauss_legendre_half<double>(24);
    double sum = 0;
    for (std::size_t i = 0; i < q.size(); ++i)
        for (int j = 0; j < 48; ++j) {
            const double phi = 2 * 3.14159265358979323846 * (j + 0.5) / 48;
            sum += q.weights[i] * q.nodes[i] * f(direction(upper ? q.nodes[i] : -q.nodes[i], phi)) * 2 * 3.14159265358979323846 / 48;
        }
    return sum;
}
}  // namespace

TEST_CASE("the BRDF and BTDF integrate to the albedo and transmittance") {
    // The flux functions use the mode-0 field and the exact hemispherical totals; the BSDFs sum all modes at
    // true angles, through the boundaries' lobes (rough) or as source-function integrals (smooth: docs/physics.md
    // section 6), the unscattered beam a delta carried separately (direct_*). They agree within the integration
    // (24 x 48 points): measured (MESSAGE) at M = 16 <= 6e-6 rough and <= 2.0e-5 smooth (the normal's T). Bounds 2e-5
    // and 5e-5. (They were 5e-4 and 2e-2 while the smooth exit was interpolated between ordinates: 1.4e-2.)
    const auto slab = Slab<double>::from_transparency(0.9, 0.8, 0.5);
    SUBCASE("rough boundaries (Stam's skin)") {
        const auto layer = solve_layer(slab, RoughDielectric<double>(0.3, 1.0, 1.4), RoughDielectric<double>(0.3, 1.4, 1.0),
                                       with_ordinates(16));
        for (double mu : {1.0, 0.7, 0.3}) {
            const Vec3<double> wi = direction(mu, 0.0);
            const double r = hemisphere_integral([&](Vec3<double> o) { return layer.subsurface_brdf(wi, o); }, true);
            const double t = hemisphere_integral([&](Vec3<double> o) { return layer.btdf(wi, o); }, false);
            MESSAGE("rough, mu0 = " << mu << ": int r_s = " << r << " vs " << layer.reflectance(mu).subsurface
                                    << ", int t_s = " << t << " vs " << layer.transmittance(mu));
            CHECK(std::fabs(r - layer.reflectance(mu).subsurface) < 2e-5);
            CHECK(std::fabs(t - layer.transmittance(mu)) < 2e-5);
        }
    }
    SUBCASE("smooth boundaries: scattered light plus the unscattered delta and delta-M's forward peak") {
        const auto layer = solve_layer(slab, SmoothDielectric<double>(1.0, 1.4), SmoothDielectric<double>(1.4, 1.0),
                                       with_ordinates(16));
        stratum::LayeredSurface<double>::Workspace ws;  // (it keeps the incidence's field)
        for (double mu : {1.0, 0.7, 0.3}) {
            const Vec3<double> wi = direction(mu, 0.0);
            const double r = hemisphere_integral([&](Vec3<double> o) { return layer.subsurface_brdf(wi, o, ws); }, true);
            const double t = hemisphere_integral([&](Vec3<double> o) { return layer.btdf(wi, o, ws); }, false);
            const double r_delta = layer.direct_reflectance(mu) + layer.forward_peak_reflectance(mu);
            const double t_delta = layer.direct_transmittance(mu) + layer.forward_peak_transmittance(mu);
            MESSAGE("smooth, mu0 = " << mu << ": int r_s + deltas = " << r + r_delta << " vs "
                                     << layer.reflectance(mu).subsurface << ", int t_s + deltas = " << t + t_delta
                                     << " vs " << layer.transmittance(mu));
            CHECK(std::fabs(r + r_delta - layer.reflectance(mu).subsurface) < 5e-5);
            CHECK(std::fabs(t + t_delta - layer.transmittance(mu)) < 5e-5);
        }
    }
}

TEST_CASE("at normal incidence the BRDF does not depend on the azimuth, and it is continuous there") {
    // A beam along the normal has no azimuthal modes k > 0 (docs/physics.md section 6: normal incidence exact).
    for (bool smooth : {false, true}) {
        const auto slab = Slab<double>::from_transparency(0.9, 0.8, 0.5);
        const auto layer = smooth ? solve_layer(slab, SmoothDielectric<double>(1.0, 1.4), SmoothDielectric<double>(1.4, 1.0),
                                                with_ordinates(16))
                                  : solve_layer(slab, RoughDielectric<double>(0.3, 1.0, 1.4),
                                                RoughDielectric<double>(0.3, 1.4, 1.0), with_ordinates(16));
        const double at_pole = layer.subsurface_brdf(direction(1.0, 0.0), direction(0.5, 0.0));
        for (double phi : {0.0, 1.5, 3.0}) {
            const double near_pole = layer.subsurface_brdf(direction(1 - 1e-12, 0.0), direction(0.5, phi));
            CHECK(std::fabs(near_pole - at_pole) <= 1e-5 * at_pole);
        }
    }
}

TEST_CASE("the tabulated boundary transmittance matches the exact integral") {
    // layer.hpp tabulates T(mu) of a rough boundary on 65 points in sqrt(mu) (exact below mu = 1/64^2): the
    // layer's zero-thickness transmittance, which is that table at the true angle, against the interface.
    const RoughDielectric<double> top(0.3, 1.0, 1.4);
    const auto layer = solve_layer(Slab<double>(0.9, 0.8, 0.0), top, Boundary<double>::index_matched(1.4), with_ordinates(8));
    double worst = 0;
    for (double mu : {1e-8, 1e-5, 1e-4, 1e-3, 0.01, 0.2, 0.55, 0.9, 1.0})
        worst = std::fmax(worst, std::fabs(layer.transmittance(mu) - top.hemispherical_transmittance(mu)));
    MESSAGE("max |table - exact| = " << worst);
    CHECK(worst < 2e-5);  // measured 1.08e-5 (the table's interpolation; its integrals are within 4.4e-7)
}

TEST_CASE("hard parameters stay finite and bounded") {
    const double inf = std::numeric_limits<double>::infinity();
    const Vec3<double> wi = direction(0.7, 0.0), wo = direction(0.4, 2.0), wt = direction(-0.5, 1.0);
    auto check_layer = [&](const stratum::LayeredSurface<double>& layer) {
        for (double mu : {1e-8, 0.3, 1.0}) {
            const auto a = layer.reflectance(mu);
            const double t = layer.transmittance(mu);
            CHECK(std::isfinite(a.total()));
            CHECK(a.surface >= 0);
            CHECK(a.subsurface >= 0);
            CHECK(t >= 0);
            CHECK(a.total() + t <= 1 + 1e-12);
        }
        for (const Vec3<double>& o : {wo, direction(1.0, 0.0), direction(1e-8, 1.0)}) {
            CHECK(std::isfinite(layer.brdf(wi, o)));
            CHECK(layer.brdf(wi, o) >= 0);
            CHECK(std::isfinite(layer.ambient(o)));
        }
        CHECK(std::isfinite(layer.btdf(wi, wt)));
        CHECK(std::isfinite(layer.brdf(direction(1e-8, 0.0), wo)));
    };
    SUBCASE("g near +-1, with and without delta-M") {
        for (double g : {-0.99, 0.0, 0.99})
            check_layer(solve_layer(Slab<double>(0.95, g, 1.0), RoughDielectric<double>(0.3, 1.0, 1.4),
                                    RoughDielectric<double>(0.3, 1.4, 1.0), with_ordinates(8, 0, true)));
        for (double g : {-0.9, 0.0, 0.9})
            check_layer(solve_layer(Slab<double>(0.95, g, 1.0), RoughDielectric<double>(0.3, 1.0, 1.4),
                                    RoughDielectric<double>(0.3, 1.4, 1.0), with_ordinates(8, 0, false)));
        // Without delta-M the 16-moment expansion of g = +-0.99 is not admissible on 8 ordinates (the discrete
        // eigenvalues lambda^2 turn negative, as DISORT's ASYMTX reports): the slab solver regularizes it.
        for (double g : {-0.99, 0.99})
            check_layer(solve_layer(Slab<double>(0.95, g, 1.0), RoughDielectric<double>(0.3, 1.0, 1.4),
                                    RoughDielectric<double>(0.3, 1.4, 1.0), with_ordinates(8, 0, false)));
    }
    SUBCASE("roughness from smooth to very rough") {
        check_layer(solve_layer(Slab<double>(0.9, 0.8, 1.0), SmoothDielectric<double>(1.0, 1.4),
                                SmoothDielectric<double>(1.4, 1.0), with_ordinates(8)));
        for (double sigma : {1e-3, 0.02, 0.3, 1.0})
            check_layer(solve_layer(Slab<double>(0.9, 0.8, 1.0), RoughDielectric<double>(sigma, 1.0, 1.4),
                                    RoughDielectric<double>(sigma, 1.4, 1.0), with_ordinates(8)));
    }
    SUBCASE("indices from matched to 2.5, and a bottom medium denser than the layer") {
        for (double eta : {1.0, 1.0 + 1e-9, 1.4, 2.5})
            check_layer(solve_layer(Slab<double>(0.9, 0.5, 1.0), RoughDielectric<double>(0.3, 1.0, eta),
                                    RoughDielectric<double>(0.3, eta, 1.0), with_ordinates(8)));
        check_layer(solve_layer(Slab<double>(0.9, 0.5, 1.0), RoughDielectric<double>(0.3, 1.0, 1.4),
                                RoughDielectric<double>(0.3, 1.4, 2.5), with_ordinates(8)));
        check_layer(solve_layer(Slab<double>(1.0, 0.5, inf), SmoothDielectric<double>(1.0, 1.4),
                                SmoothDielectric<double>(1.4, 2.5), with_ordinates(8)));
    }
    SUBCASE("ordinates from 2 to 128") {
        for (int m : {2, 3, 5, 16, 64, 128})
            check_layer(solve_layer(Slab<double>(0.9, 0.8, 1.0), SmoothDielectric<double>(1.0, 1.4),
                                    SmoothDielectric<double>(1.4, 1.0), with_ordinates(m, m >= 64 ? 2 : 0)));
    }
}

// The sweeps' sets that detail::require_escape_cones refuses: on a rule without an ordinate in a slab's escape cone
// (smooth faces of high index at 2 or 3 ordinates) the scattered light was trapped and lost, which the sweeps'
// bounds (R + T <= 1) let pass; refused now, and counted: a few percent of the sets.
int refused_sets = 0;
template <class Solve>
bool escapes(const Solve& solve) {
    try {
        (void)solve();
    } catch (const std::invalid_argument& e) {
        REQUIRE(std::string(e.what()).find("escape cone") != std::string::npos);
        ++refused_sets;
        return false;
    }
    return true;
}

TEST_CASE("randomized sweep over the parameter domain: no NaN, reflectance and transmittance in [0, 1]") {
#if defined(__SANITIZE_ADDRESS__)
    const int sets = 100;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
    const int sets = 100;
#else
    const int sets = 1000;
#endif
#else
    const int sets = 1000;
#endif
    std::mt19937_64 rng(20261122);
    auto u = [&] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };
    int failures = 0;
    for (int i = 0; i < sets; ++i) {
        const double albedo = u() < 0.1 ? 1.0 : u();
        const double g = 1.98 * u() - 0.99;
        const double tau = u() < 0.1 ? std::numeric_limits<double>::infinity() : std::pow(10.0, 8 * u() - 4);
        const double n2 = 1 + 1.5 * u(), n3 = u() < 0.5 ? 1.0 : 1 + 1.5 * u();
        const int m = 2 + static_cast<int>(11 * u());
        const bool smooth = u() < 0.2;
        const double s1 = std::pow(10.0, -2 + 2 * u()), s2 = std::pow(10.0, -2 + 2 * u());
        const LayerOptions options = with_ordinates(m, 0, u() < 0.5 || std::fabs(g) > 0.8);
        const auto solve = [&] {
            return smooth ? solve_layer(Slab<double>(albedo, g, tau), SmoothDielectric<double>(1.0, n2),
                                        SmoothDielectric<double>(n2, n3), options)
                          : solve_layer(Slab<double>(albedo, g, tau), RoughDielectric<double>(s1, 1.0, n2),
                                        RoughDielectric<double>(s2, n2, n3), options);
        };
        if (!escapes(solve)) continue;  // (too few ordinates for the escape cone: refused, counted)
        const auto layer = solve();
        const double mu = u();
        const auto a = layer.reflectance(mu);
        const double t = layer.transmittance(mu);
        const double f = layer.brdf(direction(mu, 0.0), direction(u(), 6.283 * u()));
        const bool ok = std::isfinite(a.total()) && std::isfinite(t) && std::isfinite(f) && a.surface >= 0 &&
                        a.subsurface >= 0 && t >= 0 && f >= 0 && a.total() + t <= 1 + 1e-12;
        if (!ok && failures++ < 5)
            MESSAGE("set " << i << ": albedo " << albedo << " g " << g << " tau " << tau << " n2 " << n2 << " n3 " << n3
                           << " M " << m << " smooth " << smooth << " sigma " << s1 << "," << s2 << " mu " << mu
                           << " -> R " << a.surface << " + " << a.subsurface << " T " << t << " f " << f);
    }
    CHECK(failures == 0);
    MESSAGE(refused_sets << " of " << sets << " sets refused (too few ordinates for the escape cone)");
    CHECK(refused_sets < std::max(5, sets / 100));
    refused_sets = 0;
}

TEST_CASE("randomized sweep with specular boundaries (10^4 sets): no NaN, bounded, energy never created") {
    // Smooth or index-matched faces cost no hemispherical integrals, so this sweep covers the slab solver, the
    // adding and the specular paths over many more sets than the rough sweep above.
#if defined(__SANITIZE_ADDRESS__)
    const int sets = 1000;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
    const int sets = 1000;
#else
    const int sets = 10000;
#endif
#else
    const int sets = 10000;
#endif
    // g from -0.9: below it the backward peak cannot be removed by delta-M and the truncated expansion is
    // regularized (slab.hpp), which can create up to 1% energy (g = -0.972, M = 10: R + T = 1.0106); README
    // lists this limitation.
    std::mt19937_64 rng(977);
    auto u = [&] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };
    int failures = 0;
    for (int i = 0; i < sets; ++i) {
        const double albedo = u() < 0.1 ? 1.0 : u();
        const double g = 1.89 * u() - 0.9;
        const double tau = u() < 0.1 ? std::numeric_limits<double>::infinity() : std::pow(10.0, 8 * u() - 4);
        const double n2 = u() < 0.2 ? 1.0 : 1 + 1.5 * u(), n3 = u() < 0.5 ? 1.0 : 1 + 1.5 * u();
        const int m = 2 + static_cast<int>(11 * u());
        const auto solve = [&] {
            return solve_layer(Slab<double>(albedo, g, tau), SmoothDielectric<double>(1.0, n2),
                               SmoothDielectric<double>(n2, n3), with_ordinates(m, 0, true));
        };
        if (!escapes(solve)) continue;  // (too few ordinates for the escape cone: refused, counted)
        const auto layer = solve();
        const double mu = u();
        const auto a = layer.reflectance(mu);
        const double t = layer.transmittance(mu);
        const double f = layer.subsurface_brdf(direction(mu, 0.0), direction(u(), 6.283 * u()));
        const double ft = layer.btdf(direction(mu, 0.0), direction(-u(), 6.283 * u()));
        const bool ok = std::isfinite(a.total()) && std::isfinite(t) && std::isfinite(f) && std::isfinite(ft) &&
                        a.surface >= 0 && a.subsurface >= 0 && t >= 0 && a.total() + t <= 1 + 1e-12 &&
                        layer.direct_transmittance(mu) <= t + 1e-2;
        if (!ok && failures++ < 5)
            MESSAGE("set " << i << ": albedo " << albedo << " g " << g << " tau " << tau << " n2 " << n2 << " n3 " << n3
                           << " M " << m << " mu " << mu << " -> R " << a.surface << " + " << a.subsurface << " T " << t
                           << " direct T " << layer.direct_transmittance(mu) << " f " << f << " ft " << ft);
    }
    CHECK(failures == 0);
    MESSAGE(refused_sets << " of " << sets << " sets refused (too few ordinates for the escape cone)");
    CHECK(refused_sets < std::max(5, sets / 100));
    refused_sets = 0;
}

TEST_CASE("bad input is rejected with a message naming the parameter") {
    const RoughDielectric<double> top(0.3, 1.0, 1.4), bottom(0.3, 1.4, 1.0);
    const Slab<double> slab(0.9, 0.8, 1.0);
    CHECK_THROWS_WITH(solve_layer(slab, top, bottom, with_ordinates(0)), doctest::Contains("options.ordinates"));
    CHECK_THROWS_WITH(solve_layer(slab, top, RoughDielectric<double>(0.3, 1.33, 1.0), with_ordinates(4)),
                      doctest::Contains("disagree"));
    LayerRequest<double> r;
    r.tolerance = std::nan("");
    CHECK_THROWS_WITH(solve_layer(slab, top, bottom, with_ordinates(4), r), doctest::Contains("request.tolerance"));
    r.tolerance = 0;
    r.incidence = {0.0};
    CHECK_THROWS_WITH(solve_layer(slab, top, bottom, with_ordinates(4), r), doctest::Contains("request.incidence"));
    // Bits beyond LayerOutput::all were accepted silently; a floor's index was named eta_above (found by review).
    r.incidence.clear();
    r.outputs = static_cast<LayerOutput>(1024u);
    CHECK_THROWS_WITH(solve_layer(slab, top, bottom, with_ordinates(4), r), doctest::Contains("request.outputs = 1024"));
    CHECK_THROWS_WITH(Boundary<double>::lambertian(0.5, -1.0), doctest::Contains("eta = -1"));
}

TEST_CASE("light from below is outside a LayeredSurface's domain: 0 from every function, not the top face's inner reflection") {
    // LayeredSurface is one-sided (light from above). brdf(light below, viewer below) used to return the rough top
    // interface's reflection from inside, a value that belongs to no layer. The turned-over layer answers instead:
    // by generalized reciprocity of the whole layer (t(wi, wo) / n_o^2 = t(wo, wi) / n_i^2), its BTDF from
    // flip(wo) to flip(wi) is this layer's BTDF times (n_1 / n_3)^2, to the discretization's reciprocity error.
    const double n3 = 1.2;
    const RoughDielectric<double> top(0.3, 1.0, 1.4), bottom(0.5, 1.4, n3);
    const Slab<double> slab(0.9, 0.8, 1.0);
    const auto layer = solve_layer(slab, top, bottom, with_ordinates(12));
    const Vec3<double> below_i = direction(-0.7, 0.0), below_o = direction(-0.5, 2.0), above_o = direction(0.5, 2.0);
    REQUIRE(top.brdf(below_i, below_o) > 0);  // the value the layer used to return
    CHECK(layer.brdf(below_i, below_o) == 0.0);
    CHECK(layer.subsurface_brdf(below_i, below_o) == 0.0);
    CHECK(layer.btdf(below_i, above_o) == 0.0);
    CHECK(layer.brdf(below_i, above_o) == 0.0);
    const auto turned = solve_layer(slab, RoughDielectric<double>(0.5, n3, 1.4), RoughDielectric<double>(0.3, 1.4, 1.0),
                                    with_ordinates(12));
    const auto flip = [](Vec3<double> v) { return Vec3<double>{v.x, v.y, -v.z}; };
    const Vec3<double> wi = direction(0.7, 0.0), wo = direction(-0.5, 2.0);
    const double forward = layer.btdf(wi, wo), backward = turned.btdf(flip(wo), flip(wi));
    MESSAGE("t(wi, wo) = " << forward << ", turned over t(wo, wi) (n1/n3)^-2 = " << backward * n3 * n3);
    CHECK(backward > 0);
    CHECK(std::fabs(backward * n3 * n3 - forward) <= 5e-3 * forward);  // measured 1.0e-3 at M = 12; r_s: 4e-3
}

TEST_CASE("near conservation in float with a peaked delta-M phase function: R and T follow long double") {
    // g 0.99 with delta-M at 32 ordinates: the two smallest eigenvalues are close and their float vectors mixed; the
    // conservation mode's exact vector beside them made the basis nearly dependent (R 0, T 1.0003 at 1 - Omega =
    // 2.6e-4; found by review): the refinement replaces the value alone, and not where the vectors mix.
    const auto fluxes = [](auto real, double one_minus, double tau) {
        using R = decltype(real);
        LayerOptions o;
        o.ordinates = 32;
        LayerRequest<R> request;
        request.outputs = LayerOutput::reflectance | LayerOutput::transmittance;
        const auto l = stratum::solve_layer(Slab<R>::from_one_minus_albedo(R(one_minus), R(0.99), R(tau)),
                                            stratum::Boundary<R>::index_matched(), stratum::Boundary<R>::index_matched(), o, request);
        return std::pair<long double, long double>(l.reflectance(R(1)).total(), l.transmittance(R(1)));
    };
    for (double tau : {1.0, 100.0})
        for (double one_minus : {1.4828e-5, 7e-5, 2.604e-4, 1e-3}) {
            const auto f = fluxes(0.0f, one_minus, tau), l = fluxes(0.0L, one_minus, tau);
            INFO("tau " << tau << ", 1 - Omega " << one_minus << ": float R " << double(f.first) << " T " << double(f.second)
                        << ", long double R " << double(l.first) << " T " << double(l.second));
            // (measured: 6.7e-6 at tau 1, 2.1e-4 at tau 100, as without the refinement; with the exact vector 1.0e-3)
            CHECK(std::fabs(f.first - l.first) + std::fabs(f.second - l.second) < (tau > 10 ? 3e-4 : 2e-5));
            CHECK(f.first + f.second <= 1 + 1e-5);
        }
}
