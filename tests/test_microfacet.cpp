// Beckmann distribution and Smith shadowing for a Gaussian surface: closed forms, mpmath references,
// normalization, Smith's identity, limits, and visible-normal sampling against its pdf.
#include <doctest/doctest.h>

#include <stratum/microfacet.hpp>
#include <stratum/quadrature.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include "test_util.hpp"

using stratum::Beckmann;
using stratum::Vec3;
using stratum::gauss_legendre_half;

namespace {

constexpr double pi = 3.141592653589793238462643383279502884;
constexpr double eps = std::numeric_limits<double>::epsilon();

// Uniform in [0, 1) from the top 53 bits (std distributions differ across standard libraries).
double uniform(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1p-53; }

// cos(theta) of a direction with a = cot(theta) / alpha.
double mu_from_a(double a, double alpha) { return a * alpha / std::sqrt(1 + a * a * alpha * alpha); }

// int_lo^hi f by 16-point Gauss-Legendre on `panels` equal panels.
template <class F>
double integrate(F f, double lo, double hi, int panels) {
    static const auto rule = gauss_legendre_half<double>(16);
    double sum = 0;
    const double h = (hi - lo) / panels;
    for (int p = 0; p < panels; ++p)
        for (std::size_t k = 0; k < rule.size(); ++k) sum += rule.weights[k] * h * f(lo + h * (p + rule.nodes[k]));
    return sum;
}

}  // namespace

TEST_CASE("D at the macro normal is 1 / (2 pi sigma^2) and D cos^4 is the slope density") {
    for (double sigma : {1e-4, 0.02, 0.3, 1.0, 2.0}) {
        const Beckmann<double> b(sigma);
        CHECK(b.alpha() == doctest::Approx(std::sqrt(2.0) * sigma).epsilon(1e-15));
        CHECK(stratum_test::close_rel(b.D({0, 0, 1}), 1 / (2 * pi * sigma * sigma), 4 * eps));
        // Slopes (x, y) <-> h = normalize(-x, -y, 1): P22(x, y) = D(h) cos^4(theta_h).
        for (double x : {-0.5, 0.1, 1.3}) {
            const double y = 0.4 * x + 0.05, len = std::sqrt(1 + x * x + y * y);
            const Vec3<double> h{-x / len, -y / len, 1 / len};
            const double c4 = std::pow(h.z, 4);
            const double ref = b.slope_pdf(x, y);
            if (ref > 1e-300) CHECK(stratum_test::close_rel(b.D(h) * c4, ref, 64 * eps));
        }
    }
    const Beckmann<double> b(0.3);
    CHECK(b.D({1, 0, 0}) == 0.0);   // horizon
    CHECK(b.D({0, 0.6, -0.8}) == 0.0);  // lower hemisphere: not a facet normal
}

TEST_CASE("D is normalized over projected area: int D cos(theta_h) dw_h = 1") {
    // In t = tan(theta_h): dw = sin dtheta dphi and dtheta = cos^2 dt, so the integral is
    // 2 pi int_0^inf D(h(t)) cos^4 t dt (analytic in t); graded panels in t (the lobe has width sigma)
    // up to t = 40 sigma, beyond which exp(-t^2 / (2 sigma^2)) < 1e-300.
    for (double sigma : {1e-3, 0.02, 0.3, 1.0, 2.0}) {
        const Beckmann<double> b(sigma);
        auto f = [&](double t) {
            const double c = 1 / std::sqrt(1 + t * t);
            return 2 * pi * b.D({t * c, 0, c}) * c * c * c * c * t;
        };
        double total = 0;
        for (double lo = 0, hi = sigma / 4; lo < 40 * sigma; lo = hi, hi *= 2) total += integrate(f, lo, hi, 1);
        // 16-point Gauss per panel on an analytic integrand: error ~1e-16 per panel.
        CHECK(std::fabs(total - 1) < 1e-13);
    }
}

TEST_CASE("Smith's identity: int G1(i, h) max(0, i.h) D(h) dw_h = mu_i") {
    // Over h = (t cos phi, t sin phi, 1) / sqrt(1 + t^2), t = tan(theta_h): graded panels in t, phi on
    // [0, pi] (symmetric) split where i.h changes sign, and t split at mu/s where that split reaches pi, so
    // every panel's integrand is analytic and Gauss-Legendre converges spectrally.
    for (double sigma : {0.05, 0.3, 1.0, 2.0}) {
        const Beckmann<double> b(sigma);
        for (double mu : {0.05, 0.3, 0.7, 0.95, 1.0}) {
            const double s = std::sqrt(1 - mu * mu);
            const Vec3<double> wi{s, 0, mu};
            auto over_phi = [&](double t) {
                const double ct = 1 / std::sqrt(1 + t * t), st = t * ct;
                // i.h = s st cos(phi) + mu ct > 0  <=>  cos(phi) > -mu / (s t)
                double phi_max = pi;
                if (s * t > 0) {
                    const double c = -mu / (s * t);
                    if (c > -1) phi_max = std::acos(c);
                }
                const double jac = ct * ct * ct * t;  // dw = sin(theta) dtheta dphi = t cos^3 dt dphi
                return 2 * jac * integrate([&](double p) {
                    const Vec3<double> h{st * std::cos(p), st * std::sin(p), ct};
                    return b.G1(wi, h) * std::fmax(0.0, stratum::dot(wi, h)) * b.D(h);
                }, 0, phi_max, 4);
            };
            std::vector<double> edges{0};
            for (double e = sigma / 4; e < 40 * sigma; e *= 2) edges.push_back(e);
            edges.push_back(40 * sigma);
            // At t* = mu/s the split point phi_max = acos(-mu / (s t)) has a square-root onset: grade the
            // panels geometrically towards t* from both sides.
            const double tstar = s > 0 ? mu / s : 1e300;
            if (tstar < 40 * sigma) {
                edges.push_back(tstar);
                for (double g = tstar / 2; g > tstar * 1e-12; g /= 4) {
                    edges.push_back(tstar - g);
                    if (tstar + g < 40 * sigma) edges.push_back(tstar + g);
                }
            }
            std::sort(edges.begin(), edges.end());
            double total = 0;
            for (std::size_t i = 0; i + 1 < edges.size(); ++i) total += integrate(over_phi, edges[i], edges[i + 1], 2);
            // Spectral convergence on analytic panels: measured error ~1e-15; tolerance 1e-12.
            CHECK(std::fabs(total - mu) < 1e-12);
        }
    }
}

TEST_CASE("Smith G1 matches the frozen mpmath values at a = 0.1, 0.5, 1") {
    // tests/data/gen_microfacet.py: G1 = 1 / (1 + Lambda(a)), 40 digits. The earlier 6-digit
    // frozen values 0.298587, 0.833583, 0.975489 agree with the values below to the 6 digits given.
    struct Ref { double a, g1; };
    const Ref refs[] = {{0.1, 0.29858674638241916823}, {0.5, 0.83358255480699046274}, {1, 0.97548863292880548767}};
    for (double sigma : {0.1, 1 / std::sqrt(2.0), 1.7}) {
        const Beckmann<double> b(sigma);
        for (const Ref& r : refs) {
            const double mu = mu_from_a(r.a, b.alpha());
            // mu carries one rounding; G1's condition number in a is < 2 here: a few ulp.
            CHECK(stratum_test::close_rel(b.G1(mu), r.g1, 16 * eps));
        }
    }
}

TEST_CASE("Lambda matches mpmath on both sides of the continued-fraction switch at a = 5") {
    // tests/data/gen_microfacet.py: sigma = 0.5, exactly representable mu, 40-digit Lambda.
    struct Ref { double mu, lambda, a; };
    const Ref refs[] = {
        {0.0007, 284.45898116002052319, 0.00098995},   {0.035, 5.209649450419754072, 0.0495278},
        {0.2, 0.55752632494547340408, 0.288675},       {0.58, 0.024420191529202269816, 1.00691},
        {0.817, 0.0002397625072246010664, 2.00371},    {0.927, 1.4644042363224105744e-8, 3.49536},
        {0.9622, 1.5377766126751449119e-14, 4.99646},  {0.9623, 1.4277943023397652203e-14, 5.00348},
        {0.98, 3.4852422365465470705e-25, 6.96456},    {0.9966, 2.3179289491289390505e-132, 17.1061},
        {0.9985, 1.0854662510914607125e-294, 25.7908}};
    const Beckmann<double> b(0.5);
    for (const Ref& r : refs) {
        // Tolerance: Lambda ~ exp(-a^2) has condition number ~2a^2 in a, and a carries ~4 ulp (alpha's rounding,
        // 1 - mu^2, the sqrt and the division); plus <= 50 ulp from the a < 5 branch's cancellation
        // (documented in microfacet.hpp).
        const double tol = (64 + 8 * r.a * r.a) * eps;
        INFO("mu = " << r.mu);
        CHECK(stratum_test::close_rel(b.Lambda(r.mu), r.lambda, tol));
    }
}

TEST_CASE("Lambda and G1 at the limits: grazing, normal, tiny and large sigma") {
    for (double sigma : {1e-4, 1e-3, 0.02, 0.3, 1.0, 2.0}) {
        const Beckmann<double> b(sigma);
        CHECK(b.Lambda(0.0) == std::numeric_limits<double>::infinity());
        CHECK(b.G1(0.0) == 0.0);
        CHECK(b.Lambda(1.0) == 0.0);
        CHECK(b.G1(1.0) == 1.0);
        CHECK(b.Lambda(-0.5) == b.Lambda(0.5));  // only |mu| matters
        // Grazing: G1 ~ mu / (sigma / sqrt(2 pi)) -> 0 continuously, never NaN.
        for (double mu : {1e-300, 1e-8, 1e-4}) {
            const double g = b.G1(mu), l = b.Lambda(mu);
            CHECK(std::isfinite(l));
            CHECK(g > 0.0);
            CHECK(g <= 1.0);
        }
        CHECK(stratum_test::close_rel(b.projected_area(0.0), sigma / std::sqrt(2 * pi), 8 * eps));
        // G1 is non-decreasing in mu over a sweep that crosses the a = 5 switch (for sigma this small the
        // switch is at mu ~ 1 - 1e-9 ... so include points near 1).
        double prev = 0;
        for (int i = 0; i <= 2000; ++i) {
            const double mu = i < 1000 ? i / 1000.0 : 1 - std::pow(10.0, -3 - (i - 999) / 100.0);
            const double g = b.G1(mu);
            CHECK(g >= prev - 4 * eps);
            prev = g;
        }
    }
    // Continuity across the branch switch at a = 5 (direct formula below, continued fraction above):
    // Lambda(5 - d) / Lambda(5 + d) - 1 = 2.1157648497519748e-9 for d = 1e-10 (mpmath, 40 digits); a jump
    // between the two formulas would show on top of it. Tolerance: the documented accuracy of the two
    // branches, <= 50 ulp (direct form, cancellation 2a^2) plus 3e-15 (16-level continued fraction).
    const double d = 1e-10;
    const double below = stratum::detail::smith_lambda_gaussian(5 - d), above = stratum::detail::smith_lambda_gaussian(5 + d);
    CHECK(std::fabs((below / above - 1) - 2.1157648497519748e-9) < 50 * eps + 3e-15);
}

TEST_CASE("projected area is mu (1 + Lambda) and G1 is mu over it") {
    for (double sigma : {0.02, 0.3, 2.0}) {
        const Beckmann<double> b(sigma);
        for (double mu : {0.01, 0.2, 0.6, 0.99}) {
            CHECK(stratum_test::close_rel(b.projected_area(mu), mu * (1 + b.Lambda(mu)), 32 * eps));
            CHECK(stratum_test::close_rel(b.G1(mu), 1 / (1 + b.Lambda(mu)), 32 * eps));
        }
    }
}

TEST_CASE("float and long double agree with double") {
    const Beckmann<float> bf(0.3f);
    const Beckmann<long double> bl(0.3L);
    const Beckmann<double> bd(0.3);
    for (double mu : {0.05, 0.4, 0.9}) {
        CHECK(stratum_test::close_rel(static_cast<double>(bf.G1(static_cast<float>(mu))), bd.G1(mu), 1e-6));
        CHECK(stratum_test::close_rel(static_cast<double>(bl.G1(static_cast<long double>(mu))), bd.G1(mu), 1e-14));
    }
    const Vec3<float> hf{0.1f, 0.2f, std::sqrt(0.95f)};
    const Vec3<double> hd{0.1, 0.2, std::sqrt(0.95)};
    CHECK(stratum_test::close_rel(static_cast<double>(bf.D(hf)), bd.D(hd), 1e-5));
}

TEST_CASE("visible normals: samples follow visible_normal_pdf (chi-square) and the pdf integrates to 1") {
    // Bins: 20 in h.z (equal solid angle) x 24 in phi. Expected probability per bin from the pdf by a 4 x 4
    // Gauss rule inside the bin; bins with fewer than 20 expected counts are pooled. The statistic is compared
    // with dof + 5 sqrt(2 dof) (a ~1e-5 false-alarm rate for a chi-square variable of this size).
    std::mt19937_64 rng(20261122);
    const auto sub = gauss_legendre_half<double>(4);
    const int nz = 20, nphi = 24, n = 200000;
    struct Case { double sigma, mu, phi; bool below; };
    const Case cases[] = {{0.3, 0.8, 0.3, false}, {1.0, 0.3, 2.0, false}, {0.3, 1.0, 0.0, false},
                          {0.5, 0.05, -1.0, true}, {2.0, 0.6, 0.0, false}};
    for (const Case& c : cases) {
        const Beckmann<double> b(c.sigma);
        const double s = std::sqrt(1 - c.mu * c.mu);
        const Vec3<double> wi{s * std::cos(c.phi), s * std::sin(c.phi), c.below ? -c.mu : c.mu};
        std::vector<double> expected(nz * nphi, 0.0), observed(nz * nphi, 0.0);
        double total_p = 0;
        for (int iz = 0; iz < nz; ++iz)
            for (int ip = 0; ip < nphi; ++ip) {
                double p = 0;
                for (std::size_t a = 0; a < sub.size(); ++a)
                    for (std::size_t k = 0; k < sub.size(); ++k) {
                        const double z = (iz + sub.nodes[a]) / nz, phi = 2 * pi * (ip + sub.nodes[k]) / nphi;
                        const double st = std::sqrt(1 - z * z);
                        const Vec3<double> h{st * std::cos(phi), st * std::sin(phi), c.below ? -z : z};
                        p += sub.weights[a] * sub.weights[k] * b.visible_normal_pdf(wi, h);
                    }
                p *= (1.0 / nz) * (2 * pi / nphi);
                expected[static_cast<std::size_t>(iz * nphi + ip)] = p * n;
                total_p += p;
            }
        // The visible-normal pdf integrates to 1 (Smith's identity); the 4 x 4 per-bin rule has ~1e-4 error
        // at the kink where wi.h = 0 crosses a bin.
        CHECK(std::fabs(total_p - 1) < 2e-3);
        int wrong_side = 0;
        for (int i = 0; i < n; ++i) {
            const Vec3<double> h = b.sample_visible_normal(wi, uniform(rng), uniform(rng));
            const double z = std::fabs(h.z);
            double phi = std::atan2(h.y, h.x);
            if (phi < 0) phi += 2 * pi;
            const int iz = std::min(nz - 1, static_cast<int>(z * nz));
            const int ip = std::min(nphi - 1, static_cast<int>(phi / (2 * pi) * nphi));
            observed[static_cast<std::size_t>(iz * nphi + ip)] += 1;
            wrong_side += (h.z < 0) != c.below;
        }
        CHECK(wrong_side == 0);
        const stratum_test::ChiSquare cs = stratum_test::pooled_chi_square(expected, observed);
        const double chi2 = cs.value;
        const int dof = cs.bins;
        INFO("sigma = " << c.sigma << ", mu = " << c.mu << ": chi2 = " << chi2 << " over " << dof << " bins");
        CHECK(chi2 < dof + 5 * std::sqrt(2.0 * dof));
    }
}

TEST_CASE("erfc_inverse: erfc(x) = q to rounding, from q = 1e-290 to 2 - 1e-16") {
    // The reference refines x by Newton's method on std::erfc in long double (64-bit mantissa): x is within
    // 2 ulp of it (scaled by max(1, |x|): near q = 1, x ~ 0 is accurate in absolute terms; below q ~ 1e-292 q is
    // clamped, microfacet.hpp): std::erfc's own ~1 ulp, which bounds what any inverse built on it can reach
    // (measured 0.75 ulp here, 1.09 over 2 million q). A stop rule that left one Halley step undone would miss by
    // 1e-8 or more.
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> uniform(0, 1);
    double worst = 0;
    for (int i = 0; i < 20000; ++i) {
        const double q = i % 3 == 0 ? std::pow(10.0, -290 * uniform(rng)) : (i % 3 == 1 ? 2 * uniform(rng) : 2 - std::pow(10.0, -16 * uniform(rng)));
        const double x = stratum::detail::erfc_inverse(q);
        long double r = x;
        for (int it = 0; it < 3; ++it)
            r += (std::erfc(r) - static_cast<long double>(q)) * std::sqrt(3.14159265358979323846264L) / 2 * std::exp(r * r);
        const double err = std::fabs(static_cast<double>(x - r)) / std::fmax(1.0, std::fabs(x));
        CAPTURE(q);
        CHECK(err <= 2 * std::numeric_limits<double>::epsilon());
        worst = std::fmax(worst, err);
    }
    MESSAGE("erfc_inverse: worst error " << worst / std::numeric_limits<double>::epsilon() << " ulp");
}

TEST_CASE("sample_visible_slope inverts g(x) = (sqrt(pi)/2) A erfc(-x) + B exp(-x^2)/2 to rounding, every a") {
    // The residual of the CDF at the returned slope, in long double: at rounding level (a few eps of its
    // total), for a from 1e-3 (grazing) to 1e3 (normal incidence) and u over [0, 1), tails included.
    std::mt19937_64 rng(12);
    std::uniform_real_distribution<double> uniform(0, 1);
    double worst = 0;
    for (int i = 0; i < 20000; ++i) {
        const double a = std::pow(10.0, -3 + 6 * uniform(rng));
        const double u = i % 4 == 0 ? std::pow(10.0, -20 * uniform(rng)) : (i % 4 == 1 ? 1 - std::pow(10.0, -15 * uniform(rng)) : uniform(rng));
        const long double A = a >= 1 ? 1 : a, B = a >= 1 ? 1 / a : 1;
        auto g = [&](long double x) { return A * std::sqrt(3.14159265358979323846264L) / 2 * std::erfc(-x) + B * std::exp(-x * x) / 2; };
        const double x = stratum::detail::sample_visible_slope(a, u);
        const long double total = g(std::fmin(a, 27.0));
        const double residual = static_cast<double>(std::fabs(g(x) / total - u));
        CAPTURE(a);
        CAPTURE(u);
        REQUIRE(x <= a);
        CHECK(residual <= 8 * std::numeric_limits<double>::epsilon());
        worst = std::fmax(worst, residual);
    }
    MESSAGE("sample_visible_slope: worst residual " << worst / std::numeric_limits<double>::epsilon() << " eps");
}

TEST_CASE("sample_visible_slope in float: the CDF's residual relative to the target, tails included") {
    // Stopped at a residual of 4 eps times the target (not the total: in float a lower-tail target u total lies
    // below eps total from u ~ 1e-7 on, and the old absolute stop returned a slope whose CDF was off by 100% there).
    // Measured in long double: the residual relative to u within 8 eps, or what one ulp of the slope x changes the
    // CDF by (x ~ -9 in the far tail, where g changes by 2 x^2 eps relative over one ulp of x).
    std::mt19937_64 rng(14);
    std::uniform_real_distribution<double> uniform(0, 1);
    double worst = 0;
    for (int i = 0; i < 20000; ++i) {
        const float a = static_cast<float>(std::pow(10.0, -3 + 6 * uniform(rng)));
        const float u = i % 2 == 0 ? static_cast<float>(std::pow(10.0, -30 * uniform(rng))) : static_cast<float>(uniform(rng));
        const long double A = a >= 1 ? 1 : a, B = a >= 1 ? 1 / static_cast<long double>(a) : 1;
        auto g = [&](long double x) { return A * std::sqrt(3.14159265358979323846264L) / 2 * std::erfc(-x) + B * std::exp(-x * x) / 2; };
        const float x = stratum::detail::sample_visible_slope(a, u);
        const long double total = g(std::fmin(static_cast<long double>(a), 27.0L));
        const long double density = std::exp(-static_cast<long double>(x) * x) * (A - B * x) / total;  // dg/dx / total
        const long double ulp = std::numeric_limits<float>::epsilon() * std::fmax(1.0f, std::fabs(x));
        const double allowed = static_cast<double>(8 * std::numeric_limits<float>::epsilon() * u + 2 * density * ulp);
        const double residual = static_cast<double>(std::fabs(g(x) / total - u));
        CAPTURE(a);
        CAPTURE(u);
        REQUIRE(x <= a);
        CHECK(residual <= allowed);
        worst = std::fmax(worst, residual / allowed);
    }
    MESSAGE("float sample_visible_slope: worst residual " << worst << " of its allowance");
}

TEST_CASE("visible-normal sampling in float: within a few eps of the double sampler at the same inputs") {
    // Computed in float (Beckmann::sample_visible_normal): measured over 2e5 inputs per sigma, the normal's distance
    // from the double sampler's at the same (float) inputs is 0.6e-8 to 7e-8 typically, at most 5.1e-6 for 99.9%
    // of them, and up to 8.1e-4 (sigma 5) at u1 = 1 - 2^-24 (the CDF's upper tail, which float's u resolves to 6e-8
    // only). Bounds: 1e-5 for the 99.9% quantile, 2e-3 for all.
    std::mt19937_64 rng(15);
    std::uniform_real_distribution<double> uniform(0, 1);
    for (const float sigma : {1e-4f, 0.01f, 0.3f, 1.0f, 5.0f}) {
        const Beckmann<float> bf(sigma);
        const Beckmann<double> bd(static_cast<double>(sigma));
        std::vector<double> distance;
        for (int i = 0; i < 20000; ++i) {
            const Vec3<double> w = stratum::spherical_direction(uniform(rng), 6.283185307179586 * uniform(rng));
            const Vec3<float> wf{static_cast<float>(w.x), static_cast<float>(w.y), static_cast<float>(w.z)};
            const float u1 = std::fmin(static_cast<float>(uniform(rng)), 1 - 0x1p-24f);
            const float u2 = std::fmin(static_cast<float>(uniform(rng)), 1 - 0x1p-24f);
            const Vec3<float> hf = bf.sample_visible_normal(wf, i == 0 ? 1 - 0x1p-24f : u1, u2);
            const Vec3<double> hd = bd.sample_visible_normal({wf.x, wf.y, wf.z}, i == 0 ? 1 - 0x1p-24 : u1, u2);
            distance.push_back(stratum::length(Vec3<double>{hf.x - hd.x, hf.y - hd.y, hf.z - hd.z}));
        }
        std::sort(distance.begin(), distance.end());
        CAPTURE(sigma);
        CHECK(distance[distance.size() * 999 / 1000] < 1e-5);
        CHECK(distance.back() < 2e-3);
    }
}

TEST_CASE("visible-normal sampling never returns NaN, for any u in [0, 1) and any direction") {
    const double us[] = {0.0, 1e-300, 1e-17, 0x1p-53, 0.25, 0.5, 0.75, 1 - 0x1p-53};
    const Vec3<double> dirs[] = {{0, 0, 1}, {0, 0, -1}, {1, 0, 0}, {std::sqrt(1 - 1e-16), 0, 1e-8},
                                 {0.6, 0, 0.8}, {-0.6, 0, -0.8}, {0, -std::sqrt(1 - 1e-8), 1e-4}};
    for (double sigma : {1e-4, 0.02, 0.3, 1.0, 2.0}) {
        const Beckmann<double> b(sigma);
        for (const auto& wi : dirs)
            for (double u1 : us)
                for (double u2 : us) {
                    const Vec3<double> h = b.sample_visible_normal(wi, u1, u2);
                    REQUIRE(std::isfinite(h.x));
                    REQUIRE(std::isfinite(h.y));
                    REQUIRE(std::isfinite(h.z));
                    CHECK(std::fabs(stratum::length(h) - 1) < 1e-14);
                    CHECK(std::isfinite(b.visible_normal_pdf(wi, h)));
                }
    }
    const Beckmann<float> bf(0.3f);
    const Vec3<float> h = bf.sample_visible_normal({0.6f, 0, 0.8f}, 0.0f, 1 - 0x1p-24f);
    CHECK(std::isfinite(h.x));
    CHECK(std::isfinite(h.z));
}

TEST_CASE("invalid sigma is rejected with a message naming it") {
    CHECK_THROWS_WITH_AS(Beckmann<double>{0.0}, doctest::Contains("sigma"), std::invalid_argument);
    const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
    CHECK_THROWS_AS(Beckmann<double>{-1.0}, std::invalid_argument);
    CHECK_THROWS_AS(Beckmann<double>{nan}, std::invalid_argument);
    CHECK_THROWS_AS(Beckmann<double>{inf}, std::invalid_argument);
}
