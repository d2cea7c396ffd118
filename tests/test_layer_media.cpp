// General media in the layer solver: a phase function given by its Legendre moments (Slab::with_phase_moments).
// Checked (1) against the Henyey-Greenstein path it must reproduce when given g^l (a consistency check of the
// plumbing and of delta-M with given moments); (2) by energy conservation at albedo 1 for the Rayleigh phase
// function {1, 0, 1/10}; (3) against the independent photon Monte Carlo (tests/reference/mc_layer.hpp, which
// samples Rayleigh scattering by inverting its CDF in closed form), which also shows that the moments are used:
// the isotropic medium of the same albedo differs from the Monte Carlo by many standard errors.
#include <doctest/doctest.h>

#include <stratum/layer.hpp>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include "reference/mc_layer.hpp"
#include "test_util.hpp"

using stratum::Boundary;
using stratum::LayerOptions;
using stratum::RoughDielectric;
using stratum::Slab;
using stratum::SmoothDielectric;
using stratum::Vec3;
using stratum::solve_layer;
using stratum::solve_stack;

namespace {

const std::vector<double> rayleigh = {1.0, 0.0, 0.1};  // (3 / (16 pi)) (1 + cos^2) = (1 + (2/3) P_2 / (4/3)) / (4 pi)

LayerOptions ordinates(int m, bool delta_m = true) {
    LayerOptions o;
    o.ordinates = m;
    o.delta_m = delta_m;
    return o;
}

std::vector<double> powers(double g, int count) {
    std::vector<double> chi(static_cast<std::size_t>(count));
    double gl = 1;
    for (double& c : chi) {
        c = gl;
        gl *= g;
    }
    return chi;
}

Vec3<double> direction(double mu, double phi) {
    const double s = std::sqrt((1 - mu) * (1 + mu));
    return {s * std::cos(phi), s * std::sin(phi), mu};
}

}  // namespace

TEST_CASE("moments g^l reproduce the Henyey-Greenstein slab, with and without delta-M") {
    const RoughDielectric<double> top(0.3, 1.0, 1.4);
    const SmoothDielectric<double> bottom(1.4, 1.0);
    for (const bool delta_m : {true, false})
        for (const double g : {0.85, 0.3, -0.5}) {
            const Slab<double> hg(0.95, g, 1.5);
            const Slab<double> given = Slab<double>::with_phase_moments(0.95, powers(g, 40), 1.5);  // 40 > 2M + 1
            const auto a = solve_layer(hg, top, bottom, ordinates(8, delta_m));
            const auto b = solve_layer(given, top, bottom, ordinates(8, delta_m));
            for (const double mu : {1.0, 0.6, 0.2}) {
                INFO("delta-M " << delta_m << ", g " << g << ", mu " << mu);
                // f = g^16 as a product here and as std::pow in the HG path: a few ulp apart.
                CHECK(stratum_test::close_rel(a.reflectance(mu).subsurface, b.reflectance(mu).subsurface, 1e-13));
                CHECK(stratum_test::close_rel(a.transmittance(mu), b.transmittance(mu), 1e-13));
                CHECK(std::fabs(a.forward_peak_transmittance(mu) - b.forward_peak_transmittance(mu)) <= 1e-15);
                const Vec3<double> wi = direction(mu, 0.0), wo = direction(0.5, 2.0);
                CHECK(stratum_test::close_rel(a.brdf(wi, wo), b.brdf(wi, wo), 1e-13));
            }
        }
    // Isotropic: {1} is g = 0, the same matrices bit for bit.
    const auto iso = solve_layer(Slab<double>(0.9, 0.0, 1.0), top, bottom, ordinates(6));
    const auto given_iso = solve_layer(Slab<double>::with_phase_moments(0.9, {1.0}, 1.0), top, bottom, ordinates(6));
    CHECK(iso.transmittance(0.7) == given_iso.transmittance(0.7));
    CHECK(iso.reflectance(0.7).subsurface == given_iso.reflectance(0.7).subsurface);
}

TEST_CASE("Rayleigh scattering at albedo 1 conserves energy exactly, between matched and Fresnel faces") {
    const Slab<double> thin = Slab<double>::with_phase_moments(1.0, rayleigh, 0.3);
    const Slab<double> thick = Slab<double>::with_phase_moments(1.0, rayleigh, 20.0);
    const Boundary<double> matched = Boundary<double>::index_matched(1.0);
    const SmoothDielectric<double> top(1.0, 1.33), bottom(1.33, 1.0);
    for (const Slab<double>& slab : {thin, thick}) {
        const auto open = solve_layer(slab, matched, matched, ordinates(8));
        const auto fresnel = solve_layer(slab, top, bottom, ordinates(8));
        for (const double mu : {1.0, 0.5, 0.05}) {
            INFO("tau " << slab.optical_thickness() << " mu " << mu);
            CHECK(std::fabs(open.reflectance(mu).total() + open.transmittance(mu) - 1) < 1e-13);
            CHECK(std::fabs(fresnel.reflectance(mu).total() + fresnel.transmittance(mu) - 1) < 1e-13);
        }
    }
}

// Reflected fraction into the cone mu >= mu_lo around the normal at normal incidence (the BRDF does not depend on
// the azimuth there): 2 pi int_{mu_lo}^1 f(mu) mu dmu, 8-point Gauss-Legendre (the BRDF is smooth in mu).
double backscatter_cone(const stratum::LayeredSurface<double>& layer, double mu_lo) {
    const stratum::Quadrature<double> g = stratum::gauss_legendre_half<double>(8);
    double sum = 0;
    for (std::size_t a = 0; a < g.size(); ++a) {
        const double mu = mu_lo + (1 - mu_lo) * g.nodes[a];
        sum += g.weights[a] * layer.subsurface_brdf(direction(1.0, 0.0), direction(mu, 0.0)) * mu;
    }
    return 2 * stratum_test::pi * (1 - mu_lo) * sum;
}

TEST_CASE("Rayleigh fluxes and backscatter agree with the photon Monte Carlo; an isotropic medium's do not") {
    // tau 1, albedo 0.9, 10^6 photons per case; index-matched faces (n = 1), and a rough top (sigma 0.3, n 1.33,
    // masking-only shadowing: what the Monte Carlo's one facet interaction describes). Allowance: 4 standard
    // errors plus the solver's discretization error at M = 16 (the smooth Rayleigh phase needs no truncation;
    // 2e-4 for the matched faces, 1.2e-3 with the rough face's coupling, tests/test_layer_monte_carlo.cpp).
    // Fluxes alone hardly tell Rayleigh from isotropic scattering (both scatter half of the light backwards);
    // the backscatter cone does: Rayleigh's phase function is 1.5x the isotropic one at 180 degrees.
    const Slab<double> slab = Slab<double>::with_phase_moments(0.9, rayleigh, 1.0);
    const Slab<double> isotropic(0.9, 0.0, 1.0);
    struct Case {
        Boundary<double> top;
        mc_layer::Boundary mc_top;
        double discretization;
    };
    const Case cases[] = {
        {Boundary<double>::index_matched(1.0), mc_layer::Boundary::index_matched(1.0), 2e-4},
        {RoughDielectric<double>(0.3, 1.0, 1.33, stratum::Shadowing::masking_only), mc_layer::Boundary::gaussian(0.3, 1.0, 1.33),
         1.2e-3}};
    std::uint64_t seed = 41;
    for (const Case& c : cases) {
        const double n = c.top.eta_below();
        const Boundary<double> bottom = Boundary<double>::index_matched(n);
        const auto layer = solve_layer(slab, c.top, bottom, ordinates(16));
        const auto iso = solve_layer(isotropic, c.top, bottom, ordinates(16));
        mc_layer::Layer mc{c.mc_top, mc_layer::Boundary::index_matched(n), 0.9, 0.0, 1.0};
        mc.rayleigh = true;
        for (const double mu : {1.0, 0.5}) {
            const mc_layer::Tally t = mc_layer::trace(mc, mu, 1000000, seed++, 4, 1);
            const double r_mc = t.fraction(t.subsurface), t_mc = t.fraction(t.transmitted);
            const double r_allow = 4 * t.std_error(t.subsurface) + c.discretization;
            const double t_allow = 4 * t.std_error(t.transmitted) + c.discretization;
            const double r = layer.reflectance(mu).subsurface, tr = layer.transmittance(mu);
            MESSAGE("rough top " << c.top.rough() << ", mu " << mu << ": R " << r << " vs MC " << r_mc << " +- "
                                 << t.std_error(t.subsurface) << ", T " << tr << " vs MC " << t_mc << " +- "
                                 << t.std_error(t.transmitted) << "; isotropic R " << iso.reflectance(mu).subsurface);
            CHECK(std::fabs(r - r_mc) <= r_allow);
            CHECK(std::fabs(tr - t_mc) <= t_allow);
            if (c.top.rough() || mu != 1.0) continue;
            // The top mu^2 bin of the tally (mu^2 in [3/4, 1]) against the cone integral of the subsurface BRDF.
            const std::int64_t cone_count = t.subsurface_hist[3];
            const double cone_mc = t.fraction(cone_count), cone_allow = 4 * t.std_error(cone_count) + c.discretization;
            const double cone = backscatter_cone(layer, std::sqrt(0.75)), cone_iso = backscatter_cone(iso, std::sqrt(0.75));
            MESSAGE("backscatter cone: " << cone << " vs MC " << cone_mc << " +- " << t.std_error(cone_count)
                                         << "; isotropic " << cone_iso);
            CHECK(std::fabs(cone - cone_mc) <= cone_allow);
            CHECK(std::fabs(cone_iso - cone_mc) > 3 * cone_allow);  // the moments matter
        }
    }
}

TEST_CASE("phase moments are validated where the slab is built") {
    using Catch = std::invalid_argument;
    CHECK_THROWS_WITH_AS(Slab<double>::with_phase_moments(0.9, {}, 1.0), doctest::Contains("moments is empty"), Catch);
    CHECK_THROWS_WITH_AS(Slab<double>::with_phase_moments(0.9, {0.5, 0.1}, 1.0), doctest::Contains("moments[0]"), Catch);
    CHECK_THROWS_WITH_AS(Slab<double>::with_phase_moments(0.9, {1.0, 0.2, 1.5}, 1.0), doctest::Contains("moments[2]"), Catch);
    CHECK_THROWS_WITH_AS(Slab<double>::with_phase_moments(0.9, {1.0, std::nan("")}, 1.0), doctest::Contains("moments[1]"),
                         Catch);
    // chi_1 = +-1 (a delta): named as the moment given, with g's range (it said "g = 1"; found by review)
    CHECK_THROWS_WITH_AS(Slab<double>::with_phase_moments(0.9, {1.0, 1.0}, 1.0), doctest::Contains("moments[1] = 1 is outside the allowed range (-1, 1)"), Catch);
    CHECK_THROWS_WITH_AS(Slab<double>::with_phase_moments(0.9, {1.0, -1.0}, 1.0), doctest::Contains("moments[1]"), Catch);
    CHECK_THROWS_WITH_AS(Slab<double>::with_phase_moments(1.5, rayleigh, 1.0), doctest::Contains("albedo"), Catch);
    const Slab<double> s = Slab<double>::with_phase_moments(0.9, rayleigh, 1.0);
    CHECK(s.g() == 0.0);
    CHECK_FALSE(s.henyey_greenstein());
    CHECK(s.phase_moments() == rayleigh);
    CHECK(Slab<double>(0.9, 0.5, 1.0).henyey_greenstein());
}

TEST_CASE("delta-M is left out where it would leave no phase function: chi_2M = 1 (found by review)") {
    // {1, 0.5, 1}: three quarters forward and a quarter backward delta, realizable; at M = 1 delta-M's f = chi_2 = 1
    // divided by 1 - f = 0 and the slab was refused ("chi[1] = -inf"; at albedo 1 "one_minus_albedo = -nan"); the
    // same for {1, 0.5, -1, 0.5, 1} at M = 2. Truncated plainly instead: finite, and at albedo 1 between
    // index-matched faces every bit of light is reflected or transmitted (a delta-M whose scaled moments leave [-1, 1]
    // is also left out).
    const std::vector<std::vector<double>> sets = {{1.0, 0.5, 1.0}, {1.0, 0.5, -1.0, 0.5, 1.0}};
    for (int m = 1; m <= 2; ++m)
        for (const double albedo : {0.8, 1.0}) {
            const auto layer = solve_layer(Slab<double>::with_phase_moments(albedo, sets[static_cast<std::size_t>(m - 1)], 1.0),
                                           Boundary<double>::index_matched(), Boundary<double>::index_matched(), ordinates(m));
            for (const double mu : {1.0, 0.5, 0.1}) {
                const double r = layer.reflectance(mu).total(), t = layer.transmittance(mu);
                INFO("M = " << m << ", albedo " << albedo << ", mu " << mu << ": R " << r << ", T " << t);
                CHECK(std::isfinite(r));
                CHECK(r >= 0);
                CHECK(t >= 0);
                if (albedo == 1.0) CHECK(r + t == doctest::Approx(1.0).epsilon(1e-12));
                else CHECK(r + t < 1);
            }
        }
}

// 2 E_3(tau) = 2 int_0^1 mu e^{-tau/mu} dmu: the diffuse transmittance of a purely absorbing slab (midpoint rule,
// 200000 points: the integrand is smooth, error ~1e-11).
double two_e3(double tau) {
    const int n = 200000;
    double sum = 0;
    for (int i = 0; i < n; ++i) {
        const double mu = (i + 0.5) / n;
        sum += mu * std::exp(-tau / mu);
    }
    return 2 * sum / n;
}

TEST_CASE("a Lambertian floor: closed forms for an empty and for a purely absorbing slab over it") {
    const Boundary<double> open = Boundary<double>::index_matched(1.0);
    const Boundary<double> floor = Boundary<double>::lambertian(0.6);
    // No slab (tau = 0): the floor itself, R = A at every incidence, BRDF A / pi everywhere, nothing transmitted.
    const auto bare = solve_layer(Slab<double>(0.9, 0.5, 0.0), open, floor, ordinates(8));
    for (const double mu : {1.0, 0.7, 0.2}) {
        CHECK(std::fabs(bare.reflectance(mu).total() - 0.6) < 1e-14);
        CHECK(bare.transmittance(mu) == 0.0);
        CHECK(bare.direct_reflectance(mu) == 0.0);
        for (const double mo : {0.95, 0.5, 0.1})
            CHECK(std::fabs(bare.subsurface_brdf(direction(mu, 0.0), direction(mo, 2.0)) - 0.6 / stratum_test::pi) < 1e-14);
        CHECK(bare.btdf(direction(mu, 0.0), direction(-0.5, 2.0)) == 0.0);
    }
    // A purely absorbing slab over the floor: R = A e^{-tau / mu0} 2 E_3(tau) (down unscattered, diffused, up with
    // the diffuse transmittance; an index-matched top reflects nothing back). The beam is exact at its angle
    // (docs/physics.md section 6), so the only error is the ordinates' quadrature of 2 E_3, the same at every
    // incidence: measured 9.8e-8 (M = 16) and 3.0e-11 (M = 32) relative. (With the beam interpolated onto the
    // ordinates, as before: 4.4e-5 and 2.3e-6 at mu0 = 0.5.)
    const double tau = 0.5, a = 0.6, e3 = two_e3(tau);
    for (const int m : {16, 32}) {
        const auto layer = solve_layer(Slab<double>(0.0, 0.0, tau), open, floor, ordinates(m));
        for (const double mu : {1.0, 0.5, 0.07}) {
            const double exact = a * std::exp(-tau / mu) * e3;
            const double error = std::fabs(layer.reflectance(mu).total() - exact) / exact;
            INFO("M " << m << " mu0 " << mu << ": relative error " << error);
            CHECK(error < (m == 16 ? 1.5e-7 : 1e-10));
        }
    }
}

TEST_CASE("a Lambertian floor under a rough face: the face's totals added in closed form") {
    // No slab (tau = 0) between a rough top and a floor of albedo A: what enters is re-emitted diffusely by the floor
    // at every bounce, so R(mu) = r(mu) + t(mu) A T_d / (1 - A R_d) with r, t the face's directional totals from above
    // (RoughDielectric::hemispherical_totals) and T_d, R_d its cosine-weighted totals from below (200 Gauss points
    // here, not the solver's ordinates). Measured at M = 16: 1.2e-7 (sigma 0.3) and 4.3e-6 (sigma 0.1), 4e-5 and 2.4e-4
    // at M = 8 (the diffuse totals on the ordinates). The rough top's floor operators are the solver's own (a smooth
    // top takes the floor in closed form): with their kernel halved R fell from 0.43 to 0.23 and passed every other
    // test (found by mutation testing).
    const double A = 0.8;
    for (const double sigma : {0.3, 0.1}) {
        const RoughDielectric<double> top(sigma, 1.0, 1.4), inside(sigma, 1.4, 1.0);
        const stratum::Quadrature<double> g = stratum::gauss_legendre_half<double>(200);
        double T_d = 0, R_d = 0;
        for (std::size_t j = 0; j < g.size(); ++j) {
            const auto h = inside.hemispherical_totals(g.nodes[j]);
            T_d += 2 * g.weights[j] * g.nodes[j] * h.transmittance;
            R_d += 2 * g.weights[j] * g.nodes[j] * h.reflectance;
        }
        const auto layer = solve_layer(Slab<double>(0.0, 0.0, 0.0), top, Boundary<double>::lambertian(A, 1.4), ordinates(16));
        for (const double mu : {1.0, 0.6, 0.2}) {
            const auto h = top.hemispherical_totals(mu);
            const double exact = h.reflectance + h.transmittance * A * T_d / (1 - A * R_d);
            CAPTURE(sigma);
            CAPTURE(mu);
            CHECK(std::fabs(layer.reflectance(mu).total() - exact) <= (sigma > 0.2 ? 3e-7 : 1e-5));
        }
    }
}

TEST_CASE("over a Lambertian floor under a smooth top the BRDF integrates to the subsurface reflectance") {
    // The BRDF at true angles (the floor's radiance leaving at the exact exit angle, attenuated through the slab)
    // against reflectance(mu).subsurface, which is computed on the ordinates: 64 Gauss cosines x 32 azimuths.
    // Measured within 1.9e-7; with the floor's radiance not attenuated at the exit the two were 7e-2 to 0.12 apart
    // (found by mutation testing).
    const auto q = stratum::gauss_legendre_half<double>(64);
    for (const double omega : {0.0, 0.5}) {
        const auto layer = solve_layer(Slab<double>(omega, 0.0, 0.5), SmoothDielectric<double>(1.0, 1.5),
                                       Boundary<double>::lambertian(0.8, 1.5), ordinates(16));
        for (const double mu : {0.9, 0.5}) {
            double integral = 0;
            for (std::size_t j = 0; j < q.size(); ++j)
                for (int p = 0; p < 32; ++p)
                    integral += q.weights[j] * q.nodes[j] * 2 * stratum_test::pi / 32 *
                                layer.subsurface_brdf(direction(mu, 0.0), direction(q.nodes[j], (p + 0.5) * 2 * stratum_test::pi / 32));
            CAPTURE(omega);
            CAPTURE(mu);
            CHECK(std::fabs(integral - layer.reflectance(mu).subsurface) <= 1e-6);
        }
    }
}

TEST_CASE("a white floor under a conservative slab reflects everything; a floor under an opaque slab changes nothing") {
    const Boundary<double> white = Boundary<double>::lambertian(1.0), white_dense = Boundary<double>::lambertian(1.0, 1.4);
    const Slab<double> slab(1.0, 0.7, 2.0);
    const auto open = solve_layer(slab, Boundary<double>::index_matched(1.0), white, ordinates(8));
    const auto fresnel = solve_layer(slab, SmoothDielectric<double>(1.0, 1.4), white_dense, ordinates(8));
    const auto rayleigh_layer = solve_layer(Slab<double>::with_phase_moments(1.0, rayleigh, 0.7),
                                            SmoothDielectric<double>(1.0, 1.4), white_dense, ordinates(8));
    for (const double mu : {1.0, 0.5, 0.05}) {
        CHECK(std::fabs(open.reflectance(mu).total() - 1) < 1e-13);
        CHECK(std::fabs(fresnel.reflectance(mu).total() - 1) < 1e-13);
        CHECK(std::fabs(rayleigh_layer.reflectance(mu).total() - 1) < 1e-13);
    }
    const Slab<double> opaque(0.9, 0.8, std::numeric_limits<double>::infinity());
    const auto over_floor = solve_layer(opaque, SmoothDielectric<double>(1.0, 1.4), white_dense, ordinates(8));
    const auto alone = solve_layer(opaque, SmoothDielectric<double>(1.0, 1.4), SmoothDielectric<double>(1.4, 1.0), ordinates(8));
    CHECK(std::fabs(over_floor.reflectance(0.6).total() - alone.reflectance(0.6).total()) < 1e-15);
}

template <class Real>
double worst_from_semi_infinite(const Boundary<Real>& top, int m, Real g, double tau_from, double tau_to) {
    LayerOptions o;
    o.ordinates = m;
    stratum::LayerRequest<Real> request;
    request.outputs = stratum::LayerOutput::reflectance;
    const Boundary<Real> white = Boundary<Real>::lambertian(Real(1), Real(1.4));
    const auto infinite = solve_layer(Slab<Real>(Real(1), g, std::numeric_limits<Real>::infinity()), top, white, o, request);
    double worst = 0;
    for (double tau = tau_from; tau <= tau_to; tau *= 1.7782794100389228) {  // (10^(1/4))
        const auto layer = solve_layer(Slab<Real>(Real(1), g, static_cast<Real>(tau)), top, white, o, request);
        for (const Real mu : {Real(1), Real(0.5), Real(0.1)}) {
            const double r = static_cast<double>(layer.reflectance(mu).total());
            const double e = std::fabs(r - static_cast<double>(infinite.reflectance(mu).total()));
            worst = std::isfinite(r) ? std::fmax(worst, e) : HUGE_VAL;
        }
    }
    return worst;
}

TEST_CASE("a white floor under a lossless slab too thick for light to reach it: the semi-infinite layer's R (found by review)") {
    // The floor's coupling is singular to rounding when the slab lets through less than about eps: a non-absorbing
    // slab of tau 3e16 over a white floor gave R = 7e259 (double), 8e17 at tau 1e8 (float, g 0.8), 31 under a rough
    // top at tau 1e20. Beyond T < 4 eps (the diffusion bound) the floor is solved as black; R then meets the
    // semi-infinite layer's continuously across that limit: measured worst 1.9e-15 (double, tau 1e10 to 1e21) and
    // 8.3e-7 (float, 1e3 to 1e12), smooth and rough tops, 3 and 12 ordinates.
    for (const int m : {3, 12}) {
        CHECK(worst_from_semi_infinite<double>(SmoothDielectric<double>(1, 1.4), m, 0.0, 1e10, 1e21) < 1e-14);
        CHECK(worst_from_semi_infinite<double>(RoughDielectric<double>(0.3, 1, 1.4), m, 0.5, 1e10, 1e21) < 1e-14);
        CHECK(worst_from_semi_infinite<float>(SmoothDielectric<float>(1, 1.4f), m, 0.8f, 1e3, 1e12) < 4e-6);
        CHECK(worst_from_semi_infinite<float>(RoughDielectric<float>(0.3f, 1, 1.4f), m, 0.5f, 1e3, 1e12) < 4e-6);
    }
    // Prepared faces (whose floor operators are the bright floor's) give the plain solve's R.
    LayerOptions o8 = ordinates(8);
    const stratum::PreparedBoundary<double> rough_top(Boundary<double>(RoughDielectric<double>(0.3, 1, 1.4)), o8);
    const stratum::PreparedBoundary<double> white_floor(Boundary<double>::lambertian(1.0, 1.4), o8);
    for (const double tau : {1e14, 1e20}) {
        const auto prepared = solve_layer(Slab<double>(1.0, 0.5, tau), rough_top, white_floor);
        const auto plain = solve_layer(Slab<double>(1.0, 0.5, tau), RoughDielectric<double>(0.3, 1, 1.4),
                                       Boundary<double>::lambertian(1.0, 1.4), o8);
        CHECK(prepared.reflectance(0.5).total() == doctest::Approx(plain.reflectance(0.5).total()).epsilon(1e-13));
    }
    // Beyond the limit bottom() says what was solved: a black floor of the same index.
    const auto thick = solve_layer(Slab<double>(1.0, 0.0, 1e17), SmoothDielectric<double>(1, 1.4),
                                   Boundary<double>::lambertian(1.0, 1.4), ordinates(4));
    CHECK(thick.bottom().lambertian());
    CHECK(thick.bottom().floor_albedo() == 0.0);
    CHECK(thick.bottom().eta_above() == 1.4);
    // With depths requested the floor could not be dropped, and the solve broke down, R itself: 3.3e16 in float at
    // tau 1e8 (found by review). Refused now, naming the request; just below the limit it solves.
    stratum::LayerRequest<float> depths;
    depths.depths = {0.0f, 5e7f, 1e8f};
    LayerOptions o3 = ordinates(3);
    CHECK_THROWS_WITH_AS(solve_layer(Slab<float>::with_phase_moments(1.0f, {1.0f, 0.0f, 0.1f}, 1e8f), SmoothDielectric<float>(1, 1.8f),
                                     Boundary<float>::lambertian(1.0f, 1.8f), o3, depths),
                         doctest::Contains("request.depths"), std::invalid_argument);
    depths.depths = {0.0f, 1e5f, 2e5f};
    const auto below_limit = solve_layer(Slab<float>::with_phase_moments(1.0f, {1.0f, 0.0f, 0.1f}, 2e5f),
                                         SmoothDielectric<float>(1, 1.8f), Boundary<float>::lambertian(1.0f, 1.8f), o3, depths);
    CHECK(below_limit.reflectance(1.0f).total() == doctest::Approx(1.0).epsilon(1e-3));  // (a white floor, no absorption)
}

TEST_CASE("a Lambertian floor is only a bottom boundary, and its albedo is validated") {
    const Boundary<double> floor = Boundary<double>::lambertian(0.5);
    const Boundary<double> open = Boundary<double>::index_matched(1.0);
    const Slab<double> slab(0.9, 0.5, 1.0);
    CHECK_THROWS_WITH_AS(solve_layer(slab, floor, open), doctest::Contains("not the top"), std::invalid_argument);
    CHECK_THROWS_WITH_AS(solve_stack<double>(open, {slab, slab}, {floor}, open), doctest::Contains("not interior[0]"),
                         std::invalid_argument);
    CHECK_THROWS_WITH_AS(Boundary<double>::lambertian(1.5), doctest::Contains("albedo"), std::invalid_argument);
    CHECK_THROWS_WITH_AS(Boundary<double>::lambertian(std::nan("")), doctest::Contains("albedo"), std::invalid_argument);
    CHECK(floor.lambertian());
    CHECK(floor.floor_albedo() == 0.5);
    CHECK_FALSE(open.lambertian());
}
