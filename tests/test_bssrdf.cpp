// bssrdf.hpp: the dipole as a renderer's BSSRDF. S_w's normalization by quadrature; the probe sampler against its
// density on a plane (closed form and chi-square of the hit radii) and, unbiased, on a sphere (the integral of
// the profile over the sphere by quadrature); Hery's recipe round trip; misuse refused. docs/physics.md section 8.
#include <stratum/bssrdf.hpp>

#include <doctest/doctest.h>

#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include <stratum/henyey_greenstein.hpp>
#include <stratum/quadrature.hpp>

#include "test_util.hpp"

using namespace stratum;
using stratum_test::pi;
using stratum_test::uniform;

namespace {

// Skin in 1/mm (Jensen et al. 2001, Table 1, skin 1: sigma_a, sigma_s' per channel), eta 1.3.
DipoleBSSRDF<double, 3> skin(double quantile = 0.999) {
    return DipoleBSSRDF<double, 3>(make_dipoles<double, 3>({0.032, 0.17, 0.48}, {0.74, 0.88, 1.01}, 1.3), quantile);
}

}  // namespace

TEST_CASE("BSSRDF: S_w integrates to 1 over the hemisphere, with the cosine") {
    const Quadrature<double> g = gauss_legendre_half<double>(64);
    for (double eta : {1.0, 1.3, 1.5, 2.5}) {
        const DipoleBSSRDF<double, 1> b(std::array<Dipole<double>, 1>{Dipole<double>(0.1, 1.0, eta, DiffuseFresnel::exact)});
        double sum = 0;
        for (std::size_t i = 0; i < g.size(); ++i)
            sum += 2 * pi * g.weights[i] * g.nodes[i] * b.Sw(Vec3<double>{std::sqrt(1 - g.nodes[i] * g.nodes[i]), 0, g.nodes[i]});
        INFO("eta " << eta);
        CHECK(sum == doctest::Approx(1.0).epsilon(1e-9));
        CHECK(b.exit_transmittance({0, 0, 1}) == doctest::Approx(1 - fresnel_dielectric(1.0, eta)).epsilon(1e-15));
    }
}

TEST_CASE("BSSRDF probes on a plane: the hit density is the closed form, the radii follow it (chi-square)") {
    const DipoleBSSRDF<double, 3> b = skin();
    // On the plane z = 0 (normal z) only the normal axis hits: pdf = 1/2 sum_c (1/3) sigma_c^2 e^{-sigma_c r}/(2 pi).
    for (double r : {0.0, 0.3, 1.0, 4.0}) {
        double expected = 0;
        for (const auto& ch : b.channels()) expected += 0.5 / 3 * ch.sigma_tr() * ch.sigma_tr() * std::exp(-ch.sigma_tr() * r) / (2 * pi);
        CHECK(b.pdf({r * 0.6, r * 0.8, 0}, {0, 0, 1}) == doctest::Approx(expected).epsilon(1e-14));
    }
    // Hits of 200000 probes on the plane, binned in r; misses (tangent axes) in a bin of their own (expected 1/2).
    std::mt19937_64 rng(3);
    const int n = 200000, bins = 40;
    const double r_max = 20.0;
    std::vector<double> observed(bins + 2, 0.0), expected(bins + 2, 0.0);
    for (int i = 0; i < n; ++i) {
        const ProbeSample<double> p = b.sample_probe(uniform(rng), uniform(rng), uniform(rng));
        REQUIRE(p.valid());
        // The segment origin + s axis meets z = 0 where origin.z + s axis.z = 0, within the half length.
        if (p.axis.z == 0 || std::fabs(p.origin.z / p.axis.z) > p.half_length) {
            observed[bins + 1] += 1;
            continue;
        }
        const double r = std::hypot(p.origin.x, p.origin.y);
        observed[r < r_max ? static_cast<std::size_t>(r / r_max * bins) : bins] += 1;
    }
    const Quadrature<double> g = gauss_legendre_half<double>(16);
    double total = 0;
    for (int k = 0; k < bins; ++k) {
        double p = 0;
        for (std::size_t j = 0; j < g.size(); ++j) {
            const double r = (k + g.nodes[j]) * r_max / bins;
            p += g.weights[j] * r_max / bins * 2 * pi * r * b.pdf({r, 0, 0}, {0, 0, 1});
        }
        expected[static_cast<std::size_t>(k)] = p * n;
        total += p;
    }
    expected[bins] = (0.5 - total) * n;
    expected[bins + 1] = 0.5 * n;
    const stratum_test::ChiSquare cs = stratum_test::pooled_chi_square(expected, observed);
    INFO("chi2 " << cs.value << " over " << cs.bins << " bins");
    CHECK(cs.value < cs.bins + 5 * std::sqrt(2.0 * cs.bins));
}

TEST_CASE("BSSRDF probes on a sphere: sum over hits of g / pdf estimates the integral of g over the surface") {
    // A sphere of radius 1 mm through po = (0, 0, 0) with outward normal z at po: centre (0, 0, -1). g = R_d of
    // the red channel at the straight distance, integrated over the sphere by quadrature in the polar angle from po.
    const DipoleBSSRDF<double, 3> b = skin(1 - 1e-12);  // probes long enough to reach the whole sphere
    const Vec3<double> centre{0, 0, -1};
    const auto& red = b.channels()[0];
    const Quadrature<double> g = gauss_legendre<double>(200);
    double reference = 0;  // int_0^pi R_d(2 sin(theta/2)) 2 pi sin(theta) dtheta on the unit sphere
    for (std::size_t i = 0; i < g.size(); ++i) {
        const double theta = pi / 2 * (g.nodes[i] + 1);
        reference += pi / 2 * g.weights[i] * red.Rd(2 * std::sin(theta / 2)) * 2 * pi * std::sin(theta);
    }
    std::mt19937_64 rng(5);
    const int n = 400000;
    double sum = 0, sum2 = 0;
    for (int i = 0; i < n; ++i) {
        const ProbeSample<double> p = b.sample_probe(uniform(rng), uniform(rng), uniform(rng));
        // |origin + s axis - centre|^2 = 1: s^2 + 2 s (axis . oc) + |oc|^2 - 1 = 0.
        const Vec3<double> oc = p.origin - centre;
        const double h = dot(p.axis, oc), c = dot(oc, oc) - 1, disc = h * h - c;
        double x = 0;
        if (disc > 0)
            for (double s : {-h - std::sqrt(disc), -h + std::sqrt(disc)}) {
                if (std::fabs(s) > p.half_length) continue;
                const Vec3<double> hit = p.origin + s * p.axis;
                const Vec3<double> normal = hit - centre;
                x += red.Rd(length(hit)) / b.pdf(hit, normal);
            }
        sum += x;
        sum2 += x * x;
    }
    const double mean = sum / n, se = std::sqrt((sum2 / n - mean * mean) / n);
    MESSAGE("sphere: estimate " << mean << " +- " << se << ", quadrature " << reference);
    CHECK(std::fabs(mean - reference) <= 4 * se);
    CHECK(se < 0.01 * reference);
}

TEST_CASE("BSSRDF: Hery's recipe gives the painted colour and mean free path; misuse refused") {
    const std::array<double, 3> Rd = {0.63, 0.44, 0.34}, ld = {1.2, 0.6, 0.3};
    const auto b = DipoleBSSRDF<double, 3>::from_reflectance(Rd, ld, 1.3);
    for (std::size_t c = 0; c < 3; ++c) {
        CHECK(b.channels()[c].total_reflectance() == doctest::Approx(Rd[c]).epsilon(1e-13));
        CHECK(b.channels()[c].diffuse_mean_free_path() == doctest::Approx(ld[c]).epsilon(1e-13));
    }
    // The per-texel form: AlphaPrimeTable then Dipole::from_albedo gives the same medium.
    const AlphaPrimeTable<double> table(1.3);
    const Dipole<double> texel = Dipole<double>::from_albedo(table(Rd[1]), ld[1], 1.3);
    CHECK(texel.total_reflectance() == doctest::Approx(Rd[1]).epsilon(1e-11));
    CHECK(texel.sigma_a() == doctest::Approx(b.channels()[1].sigma_a()).epsilon(1e-9));
    // Different eta, no absorption, a bad quantile.
    CHECK_THROWS_AS((DipoleBSSRDF<double, 2>({Dipole<double>(0.1, 1.0, 1.3), Dipole<double>(0.1, 1.0, 1.4)})), std::invalid_argument);
    CHECK_THROWS_AS((DipoleBSSRDF<double, 1>({Dipole<double>(0.0, 1.0, 1.3)})), std::invalid_argument);
    CHECK_THROWS_AS((DipoleBSSRDF<double, 1>({Dipole<double>(0.1, 1.0, 1.3)}, 1.0)), std::invalid_argument);
    // float: the same densities to float rounding.
    const DipoleBSSRDF<float, 3> f(make_dipoles<float, 3>({0.032f, 0.17f, 0.48f}, {0.74f, 0.88f, 1.01f}, 1.3f));
    CHECK(f.pdf({0.3f, 0.1f, 0.0f}, {0.0f, 0.0f, 1.0f}) == doctest::Approx(skin().pdf({0.3, 0.1, 0.0}, {0, 0, 1})).epsilon(1e-5));
}

TEST_CASE("BSSRDF: the probe's half length is the quantile radius of the most spread channel, whichever it is") {
    // sigma_tr = sqrt(3 sigma_a (sigma_a + sigma_s')): 1.5 and 0.24738633753705963; the quantile 0.999 of
    // u e^{-u} du is u = -1 - W_-1(-0.001 / e) = 9.2334134764515857 (mpmath), so the half length is
    // u / 0.24738633753705963 = 37.323861812168092 with the spread channel second or first (with it second, a
    // probe sized by channel 0 alone was 6x short; found by mutation testing: the skin fixture's channel 0 is the
    // most spread).
    const Dipole<double> narrow(0.5, 1.0, 1.3), wide(0.02, 1.0, 1.3);
    CHECK(stratum_test::close_rel(DipoleBSSRDF<double, 2>({narrow, wide}).probe_half_length(), 37.323861812168092, 1e-12));
    CHECK(stratum_test::close_rel(DipoleBSSRDF<double, 2>({wide, narrow}).probe_half_length(), 37.323861812168092, 1e-12));
}

TEST_CASE("BSSRDF: the probe density stays a number where sigma_tr^2 overflows (found by the renderer sweep)") {
    // float sigma_tr ~ 1e30: sigma_tr^2 overflows, and on the axes the normal is perpendicular to 0 x inf was NaN.
    const DipoleBSSRDF<float, 1> tiny({Dipole<float>::from_reflectance(0.5f, 1e-30f, 1.3f)});
    REQUIRE(tiny.channels()[0].sigma_tr() > 1e20f);
    const float at_origin = tiny.pdf({0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f});
    CHECK_FALSE(std::isnan(at_origin));  // inf: the density there exceeds float's range
    // At u = sigma_tr r = 60 the density sigma_tr^2 e^{-60} / (4 pi) (the z axis, half the probability) is within
    // float's range: finite and as in double (sigma_tr^2 alone overflowed to inf there).
    const double s = tiny.channels()[0].sigma_tr();
    const float r = static_cast<float>(60 / s);
    const float p = tiny.pdf({r, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f});
    const double r_float = static_cast<double>(r);  // the distance as float holds it
    CHECK(std::isfinite(p));
    CHECK(p == doctest::Approx(0.5 * s * s * std::exp(-s * r_float) / (2 * 3.141592653589793)).epsilon(1e-4));
    CHECK(tiny.pdf({1.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}) == 0.0f);  // far out: e^{-u} underflows
}

TEST_CASE("BSSRDF: uniforms outside [0, 1) are clamped into it (found by a review sweep)") {
    // A NaN or huge u_axis made static_cast<int>(u N) INT_MIN: sample_probe (noexcept) read channels_[INT_MIN] and
    // crashed; u_axis = -0.25 read channels_[-1]; a NaN u2 gave a NaN origin that valid() accepted. Now every
    // uniform is clamped into [0, 1 - eps/2] (NaN to 0): the sample at the nearest end.
    const DipoleBSSRDF<double, 3> b = skin();
    const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
    for (double u : {nan, -1e10, -0.25, -inf, 1.0, 2.0, 1e300, inf})
        for (int which = 0; which < 3; ++which) {
            const double u_axis = which == 0 ? u : 0.3, u1 = which == 1 ? u : 0.4, u2 = which == 2 ? u : 0.6;
            const ProbeSample<double> p = b.sample_probe(u_axis, u1, u2);
            CAPTURE(u);
            CAPTURE(which);
            CHECK(p.valid());
            CHECK(p.channel >= 0);
            CHECK(p.channel < 3);
            CHECK(std::isfinite(p.origin.x));
            CHECK(std::isfinite(p.origin.y));
            CHECK(std::isfinite(p.origin.z));
        }
    // At the ends: u_axis below 0 is u_axis = 0 (the z axis, the first channel), above 1 the y axis, the last channel.
    CHECK(b.sample_probe(-1, 0.5, 0.5).channel == b.sample_probe(0, 0.5, 0.5).channel);
    CHECK(b.sample_probe(2, 0.5, 0.5).axis.y == 1);
    CHECK(b.sample_probe(2, 0.5, 0.5).channel == 2);
    // Henyey-Greenstein's sampler likewise (a NaN u2 gave a NaN direction).
    const PhaseSample<double> h = HenyeyGreenstein<double>(0.8).sample(0.3, nan);
    CHECK(std::isfinite(h.direction.x));
    CHECK(std::isfinite(h.direction.y));
}
