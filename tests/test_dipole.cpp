// The dipole: the integral identity, the inversion R_d -> alpha' (exact and tabulated), frozen values,
// limits, bad input and the radial sampler.
#include <doctest/doctest.h>

#include <stratum/dipole.hpp>
#include <stratum/quadrature.hpp>

#include <array>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "test_util.hpp"

using stratum::alpha_prime_from_reflectance;
using stratum::AlphaPrimeTable;
using stratum::DiffuseFresnel;
using stratum::Dipole;
using stratum::DipoleBoundary;
using stratum::total_diffuse_reflectance;

namespace {

struct Reference {
    std::map<std::string, long double> A;  // "fit 1.3" -> A
    struct Inv { std::string key; double rd; long double alpha; };
    std::vector<Inv> inv;
    struct Prof { double sigma_a, sigma_s, r; long double value; };
    std::vector<Prof> prof;
};

const Reference& reference() {
    static const Reference ref = [] {
        Reference out;
        std::ifstream in(STRATUM_TEST_DATA_DIR "/dipole_reference.txt");
        REQUIRE(in.good());
        std::string line;
        while (std::getline(in, line)) {
            std::istringstream ss(line);
            std::string kind;
            ss >> kind;
            if (kind == "A") {
                std::string model, eta, a;
                ss >> model >> eta >> a;
                out.A[model + " " + eta] = std::strtold(a.c_str(), nullptr);
            } else if (kind == "inv") {
                std::string model, eta, rd, a;
                ss >> model >> eta >> rd >> a;
                out.inv.push_back(
                    {model + " " + eta, std::strtod(rd.c_str(), nullptr), std::strtold(a.c_str(), nullptr)});
            } else if (kind == "prof") {
                std::string sa, ssp, r, v;
                ss >> sa >> ssp >> r >> v;
                out.prof.push_back({std::stod(sa), std::stod(ssp), std::stod(r), std::strtold(v.c_str(), nullptr)});
            }
        }
        REQUIRE(out.inv.size() > 1000);
        return out;
    }();
    return ref;
}

DipoleBoundary<double> boundary(const std::string& key) {
    const auto space = key.find(' ');
    const std::string model = key.substr(0, space);
    return DipoleBoundary<double>::from_eta(std::stod(key.substr(space + 1)),
                                            model == "fit" ? DiffuseFresnel::jensen_fit : DiffuseFresnel::exact);
}

/// int_0^inf R_d(r) 2 pi r dr by the substitution r = z_r (e^x - 1): the 1/r^3 peak at r ~ z_r (and z_v)
/// becomes a bump of unit width in x, and the e^{-sigma_tr r} tail a double-exponential decay in x (or
/// e^{-x} without absorption). Composite 20-point Gauss-Legendre on steps of 1/4 in x, in long double, up
/// to where the neglected tail is < 1e-17 of the total.
long double integrate_profile(const Dipole<double>& d) {
    static const auto rule = stratum::gauss_legendre<long double>(20);
    const long double zr = d.z_r(), zv = d.z_v(), tr = d.sigma_tr();
    const long double pi = 3.141592653589793238462643383279502884L;
    long double sum = 0;
    for (long double a = 0;; a += 0.25L) {
        long double piece = 0;
        for (std::size_t i = 0; i < rule.size(); ++i) {
            const long double x = a + 0.125L * (1 + rule.nodes[i]);
            const long double r = zr * std::expm1(x), jac = zr * std::exp(x);
            piece += rule.weights[i] * 0.125L * d.Rd(static_cast<double>(r)) * 2 * pi * r * jac;
        }
        sum += piece;
        const long double rb = zr * std::expm1(a + 0.25L);
        // Remaining tail <= alpha'/2 (z_r + z_v) / rb (the 1/r^2 tail without absorption) and, with absorption,
        // negligible once sigma_tr rb > 45 (e^{-45} ~ 3e-20 times a polynomial factor).
        if (tr * rb > 45 || (zr + zv) / rb < 1e-17L) break;
    }
    return sum;
}

}  // namespace

TEST_CASE("the radial profile integrates to the total diffuse reflectance") {
    // int_0^inf R_d(r) 2 pi r dr = (alpha'/2)(1 + e^{-(4/3) A s}) e^{-s} is exact (each pole integrates in closed
    // form); the quadrature above converges to ~1e-15, double evaluation of R_d(r) adds ~1e-16 per point.
    // 1e-9 is required; we hold 1e-13 (measured 4e-16).
    double worst = 0;
    for (double eta : {1.0, 1.3, 1.5}) {
        for (double alpha : {0.01, 0.3, 0.9, 0.999, 0.999999}) {
            const auto d = Dipole<double>::from_albedo(alpha, 1.0, eta);
            const long double integral = integrate_profile(d);
            const double expected = total_diffuse_reflectance(alpha, eta);
            worst = std::fmax(worst, std::fabs(static_cast<double>(integral) - expected) / expected);
            INFO("eta = " << eta << ", alpha' = " << alpha);
            CHECK(std::fabs(static_cast<double>(integral) - expected) <= 1e-13 * expected);
            CHECK(d.total_reflectance() == expected);
        }
        // No absorption: sigma_tr = 0, the profile decays like 1/r^3 and integrates to alpha' = 1.
        const Dipole<double> clear(0.0, 2.0, eta);
        CHECK(clear.sigma_tr() == 0.0);
        CHECK(std::fabs(static_cast<double>(integrate_profile(clear)) - 1.0) <= 1e-12);
    }
    MESSAGE("integral identity: max relative error " << worst);
}

TEST_CASE("the total diffuse reflectance reproduces the frozen reference values") {
    // Recomputed independently with mpmath (tests/data/gen_dipole.py prints them): with A = 2.602064 exactly,
    // R_d(0.5) = 0.07450687658, R_d(0.9) = 0.2991291755, R_d(0.99) = 0.6445255082, R_d(1) = 1: checked to 1e-10
    // (the closed form in double is good to ~1e-16). The frozen 6-digit values agree to 1e-6 (0.644525 is
    // 0.6445255082 truncated, not rounded; docs/physics.md section 11).
    const DipoleBoundary<double> b{1.3, 2.602064};
    CHECK(std::fabs(total_diffuse_reflectance(0.5, b) - 0.07450687658) <= 1e-10);
    CHECK(std::fabs(total_diffuse_reflectance(0.9, b) - 0.2991291755) <= 1e-10);
    CHECK(std::fabs(total_diffuse_reflectance(0.99, b) - 0.6445255082) <= 1e-10);
    CHECK(std::fabs(total_diffuse_reflectance(0.5, b) - 0.074507) <= 1e-6);
    CHECK(std::fabs(total_diffuse_reflectance(0.9, b) - 0.299129) <= 1e-6);
    CHECK(std::fabs(total_diffuse_reflectance(0.99, b) - 0.644525) <= 1e-6);
    CHECK(total_diffuse_reflectance(1.0, b) == 1.0);
    // The inverse: the frozen 8-digit values 0.59195420 and 0.97258193 belong to the unrounded fit
    // (A = 2.6020643879); with A = 2.602064 exactly mpmath gives 0.591954194 and 0.972581922.
    CHECK(std::fabs(alpha_prime_from_reflectance(0.1, 1.3) - 0.59195420) <= 5e-9);
    CHECK(std::fabs(alpha_prime_from_reflectance(0.5, 1.3) - 0.97258193) <= 5e-9);
    CHECK(std::fabs(alpha_prime_from_reflectance(0.1, b) - 0.591954194066) <= 1e-12);
    CHECK(std::fabs(alpha_prime_from_reflectance(0.5, b) - 0.972581921611) <= 1e-12);
}

TEST_CASE("A follows the chosen F_dr: 2.602064 with the Jensen fit at eta = 1.3, and the exact integral") {
    // mpmath: (1 + F_dr)/(1 - F_dr) with the fit and with the exact hemispherical integral (gen_dipole.py).
    // Tolerance: F_dr from fresnel.hpp is good to a few ulp; A amplifies by 2/(1 - F_dr)^2 ~ 6.5 at eta = 1.3.
    CHECK(std::fabs(stratum::dipole_A(1.3) - 2.602064) <= 5e-7);
    for (const auto& entry : reference().A) {
        const double a = static_cast<double>(entry.second);
        INFO(entry.first);
        CHECK(std::fabs(boundary(entry.first).A - a) <= 1e-14 * a);
    }
    CHECK(stratum::dipole_A(1.0, DiffuseFresnel::exact) == 1.0);
}

TEST_CASE("the Jensen fit changes R_d by the amounts stated in dipole.hpp") {
    // The header states the largest difference between the two F_dr models over alpha' in [0, 1]; each figure
    // is checked to the 2 digits it is given with (measured on 1e5 points).
    struct Case { double eta, abs_diff, rel_diff; };
    for (const Case c : {Case{1.0, 3.2e-4, 8.9e-4}, Case{1.3, 1.1e-4, 2.1e-4}, Case{1.5, 1.9e-4, 3.4e-4},
                         Case{2.5, 7.8e-3, 1.2e-2}}) {
        const auto fit = DipoleBoundary<double>::from_eta(c.eta);
        const auto exact = DipoleBoundary<double>::from_eta(c.eta, DiffuseFresnel::exact);
        double abs_diff = 0, rel_diff = 0;
        for (int i = 1; i <= 100000; ++i) {
            const double a = i / 100000.0;
            const double f = total_diffuse_reflectance(a, fit), e = total_diffuse_reflectance(a, exact);
            abs_diff = std::fmax(abs_diff, std::fabs(f - e));
            rel_diff = std::fmax(rel_diff, std::fabs(f - e) / e);
        }
        INFO("eta = " << c.eta << ": abs " << abs_diff << ", rel " << rel_diff);
        CHECK(std::fabs(abs_diff - c.abs_diff) <= 0.05 * c.abs_diff);
        CHECK(std::fabs(rel_diff - c.rel_diff) <= 0.05 * c.rel_diff);
    }
}

TEST_CASE("the exact inversion is within 1e-15 of mpmath roots on all of [0, 1]") {
    // Reference: bisection in s to 40 digits (gen_dipole.py) on a 201-point grid, geometric approaches to 0 and
    // 1 (down to Rd = 5e-324 and 1 - 2^-53), for 5 (model, eta) pairs. 1e-12 is required; the Halley
    // iteration converges to rounding, measured max 2.7e-16 (~1 ulp of numbers near 1). For alpha' < 1/2 the
    // result is also relatively accurate (alpha' = Rd / E(s)): 8 eps relative, measured ~2 eps, down to
    // Rd = 1e-300.
    const double eps = std::numeric_limits<double>::epsilon();
    std::map<std::string, double> worst;
    for (const auto& row : reference().inv) {
        const double got = alpha_prime_from_reflectance(row.rd, boundary(row.key));
        const long double err = std::fabs(got - row.alpha);
        worst[row.key] = std::fmax(worst[row.key], static_cast<double>(err));
        INFO(row.key << ", Rd = " << row.rd);
        CHECK(err <= 1e-15L);
        if (row.alpha < 0.5L && row.rd > 1e-300) CHECK(err <= 8 * eps * row.alpha);
    }
    for (const auto& entry : worst) MESSAGE("exact inversion, " << entry.first << ": max abs error " << entry.second);
}

TEST_CASE("alpha' -> R_d -> alpha' and R_d -> alpha' -> R_d round trips hold, both ends included") {
    const auto b = DipoleBoundary<double>::from_eta(1.3);
    const double k = 4.0 / 3 * b.A;
    std::vector<double> grid;
    for (int i = 0; i <= 20000; ++i) grid.push_back(i / 20000.0);
    for (int e = 1; e <= 32; ++e) {
        grid.push_back(std::pow(10.0, -e / 2.0));
        grid.push_back(1 - std::pow(10.0, -e / 2.0));
    }
    for (double a : grid) {
        // alpha' -> R_d -> alpha': R_d(alpha') has slope >= E(sqrt 3) ~ 0.09, so rounding R_d by eps R_d moves
        // alpha' by at most ~11 eps R_d <= 11 eps alpha'... plus the inversion's 2 eps: 16 eps absolute.
        const double back = alpha_prime_from_reflectance(total_diffuse_reflectance(a, b), b);
        INFO("alpha' = " << a);
        CHECK(std::fabs(back - a) <= 16 * std::numeric_limits<double>::epsilon());
    }
    for (double rd : grid) {
        // R_d -> alpha' -> R_d: alpha' is a double, so near alpha' = 1 (where dR_d/dalpha' = (3/(2s))|R_d'(s)|
        // <= 3(k + 2)/(4s) grows without bound) its rounding moves R_d: tolerance 4 eps + that slope times
        // 2 eps. (R_d = 1 - 1e-16 gives alpha' = 1 exactly: 1 - alpha' ~ 1e-33 is not representable.)
        const double a = alpha_prime_from_reflectance(rd, b);
        const double s = std::sqrt(3 * (1 - a));
        const double eps = std::numeric_limits<double>::epsilon();
        const double slope = s > 0 ? 3 * (k + 2) / (4 * s) : std::numeric_limits<double>::infinity();
        INFO("Rd = " << rd);
        CHECK(std::fabs(total_diffuse_reflectance(a, b) - rd) <= 4 * eps + slope * 2 * eps);
    }
}

TEST_CASE("R_d(alpha') and its inverse are monotone") {
    for (const std::string key : {"fit 1.3", "exact 1", "exact 2.5"}) {
        const auto b = boundary(key);
        const AlphaPrimeTable<double> table(b);
        double prev_rd = 0, prev_a = 0, prev_t = 0;
        for (int i = 0; i <= 100000; ++i) {
            const double x = i / 100000.0;
            const double rd = total_diffuse_reflectance(x, b), a = alpha_prime_from_reflectance(x, b), t = table(x);
            INFO(key << ", x = " << x);
            REQUIRE(rd >= prev_rd);
            REQUIRE(a >= prev_a);
            REQUIRE(t >= prev_t);
            prev_rd = rd, prev_a = a, prev_t = t;
        }
        CHECK(prev_rd == 1.0);
        CHECK(prev_a == 1.0);
        CHECK(prev_t == 1.0);
    }
}

TEST_CASE("the tabulated fast path stays within its stated error over the whole range") {
    // Stated in dipole.hpp for double: 2001 nodes <= 7e-13, 513 <= 1.6e-10, 129 <= 4e-8. Checked on 2e5 points
    // (uniform in R_d plus geometric approaches to both ends) against the exact inversion (itself 3e-16), for
    // eta in {1, 1.3, 1.5, 2.5} and both F_dr models; max_error() (measured at construction on the interval
    // midpoints) must agree with the dense maximum to 5% (the Hermite error peaks at the midpoints).
    struct Size { int n; double bound; };
    for (const std::string key : {"fit 1.3", "exact 1.3", "exact 1", "fit 1.5", "exact 2.5"}) {
        const auto b = boundary(key);
        for (const Size sz : {Size{2001, 7e-13}, Size{513, 1.6e-10}, Size{129, 4e-8}}) {
            const AlphaPrimeTable<double> table(b, sz.n);
            double worst = 0;
            for (int i = 0; i <= 200000; ++i) {
                const double rd = i / 200000.0;
                worst = std::fmax(worst, std::fabs(table(rd) - alpha_prime_from_reflectance(rd, b)));
            }
            for (int e = 1; e <= 60; ++e) {
                const double d = std::pow(10.0, -e / 4.0);
                worst = std::fmax(worst, std::fabs(table(d) - alpha_prime_from_reflectance(d, b)));
                worst = std::fmax(worst, std::fabs(table(1 - d) - alpha_prime_from_reflectance(1 - d, b)));
            }
            INFO(key << ", " << sz.n << " nodes: dense max " << worst << ", max_error() " << table.max_error());
            CHECK(worst <= sz.bound);
            CHECK(std::fabs(worst - table.max_error()) <= 0.05 * worst);
            if (key == "fit 1.3") MESSAGE("table " << sz.n << " nodes (fit, eta 1.3): max error " << worst);
        }
        CHECK(AlphaPrimeTable<double>(b)(0.0) == 0.0);
        CHECK(AlphaPrimeTable<double>(b)(1.0) == 1.0);
    }
    // float: rounding of the lookup coordinate sqrt(R_d) (size - 1) and of the Hermite sum, times the slope of
    // alpha'(R_d) (up to ~11 at R_d = 0): ~10 float eps, 1e-6. Measured 2.3e-7.
    const AlphaPrimeTable<float> tf(1.3f);
    const auto bd = DipoleBoundary<double>::from_eta(1.3);
    double worst = 0;
    for (int i = 0; i <= 100000; ++i) {
        const float rd = static_cast<float>(i) / 100000.0f;
        worst = std::fmax(worst, std::fabs(static_cast<double>(tf(rd)) - alpha_prime_from_reflectance(double(rd), bd)));
    }
    CHECK(worst <= 1e-6);
    // Out-of-range and NaN inputs are clamped, never UB or NaN.
    CHECK(tf(-1.0f) == 0.0f);
    CHECK(tf(2.0f) == 1.0f);
    CHECK(tf(std::numeric_limits<float>::quiet_NaN()) == 0.0f);
}

TEST_CASE("the radial profile matches mpmath at sample radii in double and float") {
    // gen_dipole.py evaluates R_d(r) in 40 digits (A from the fit, eta = 1.3) for skin1 red, marble blue and a
    // non-absorbing medium. double: exp and sqrt and a dozen roundings: 1e-14 relative. float: the argument
    // sigma_tr d of the exponential carries ~2 float eps relative, which exp turns into (sigma_tr d) 2 eps:
    // 4 (1 + sigma_tr r) float eps.
    const auto b = DipoleBoundary<double>::from_eta(1.3);
    const auto bf = DipoleBoundary<float>::from_eta(1.3f);
    REQUIRE(reference().prof.size() >= 18);
    for (const auto& p : reference().prof) {
        const Dipole<double> d(p.sigma_a, p.sigma_s, b);
        const Dipole<float> f(static_cast<float>(p.sigma_a), static_cast<float>(p.sigma_s), bf);
        INFO("sigma_a = " << p.sigma_a << ", sigma_s' = " << p.sigma_s << ", r = " << p.r);
        const double ref = static_cast<double>(p.value);
        CHECK(std::fabs(d.Rd(p.r) - ref) <= 1e-14 * ref);
        const double tol_f = 4 * (1 + d.sigma_tr() * p.r) * std::numeric_limits<float>::epsilon();
        if (ref > 1e-30) CHECK(std::fabs(f.Rd(static_cast<float>(p.r)) - ref) <= tol_f * ref);
    }
}

TEST_CASE("limits: r = 0 and r -> inf, alpha' -> 0 and 1, no absorption, eta = 1") {
    const Dipole<double> skin(0.032, 0.74, 1.3);
    CHECK(std::isfinite(skin.Rd(0.0)));
    CHECK(skin.Rd(0.0) > skin.Rd(0.01));
    CHECK(skin.Rd(-0.3) == skin.Rd(0.3));
    CHECK(skin.Rd(1e6) == 0.0);
    CHECK(skin.Rd(1e300) == 0.0);
    CHECK(skin.Rd(std::numeric_limits<double>::infinity()) == 0.0);
    CHECK(Dipole<float>(0.032f, 0.74f, 1.3f).Rd(3e19f) == 0.0f);  // r^2 overflows float
    // Hery's z_r = sqrt(3 (1 - alpha')) / sigma_tr is the same 1/sigma_t'.
    CHECK(stratum_test::close_rel(std::sqrt(3 * (1 - skin.alpha_prime())) / skin.sigma_tr(), skin.z_r(), 1e-15));
    CHECK(stratum_test::close_rel(skin.z_v(), skin.z_r() * (1 + 4 * skin.A() / 3), 1e-15));
    // alpha' = 0 (no scattering): nothing comes back.
    const Dipole<double> black(1.0, 0.0, 1.3);
    CHECK(black.alpha_prime() == 0.0);
    CHECK(black.Rd(0.0) == 0.0);
    CHECK(black.total_reflectance() == 0.0);
    // alpha' -> 1: the total tends to 1 like 1 - (k + 2)/2 s.
    const Dipole<double> nearly_clear(1e-12, 1.0, 1.3);
    CHECK(nearly_clear.total_reflectance() < 1.0);
    CHECK(nearly_clear.total_reflectance() > 1.0 - 1e-5);
    // No absorption: sigma_tr = 0, everything comes back; the sampler has no pdf and returns 0.
    const Dipole<double> clear(0.0, 1.0, 1.3);
    CHECK(clear.total_reflectance() == 1.0);
    CHECK(clear.diffuse_mean_free_path() == std::numeric_limits<double>::infinity());
    CHECK(std::isfinite(clear.Rd(0.0)));
    CHECK(clear.Rd(1e10) > 0.0);  // 1/r^3 tail, no exponential
    CHECK(clear.sample_radius(0.5) == 0.0);
    CHECK(clear.pdf_radius(1.0) == 0.0);
    // eta = 1 with the exact F_dr: A = 1, z_v = (7/3) z_r.
    const Dipole<double> matched(0.1, 1.0, 1.0, DiffuseFresnel::exact);
    CHECK(matched.A() == 1.0);
    CHECK(stratum_test::close_rel(matched.z_v(), 7.0 / 3 * matched.z_r(), 1e-15));
    // The (alpha', ld) and (sigma_a, sigma_s') parameterizations agree.
    const auto hery = Dipole<double>::from_albedo(skin.alpha_prime(), skin.diffuse_mean_free_path(), 1.3);
    CHECK(stratum_test::close_rel(hery.sigma_a(), 0.032, 1e-14));
    CHECK(stratum_test::close_rel(hery.sigma_s_prime(), 0.74, 1e-14));
    const auto from_rd = Dipole<double>::from_reflectance(skin.total_reflectance(), skin.diffuse_mean_free_path(), 1.3);
    CHECK(stratum_test::close_rel(from_rd.sigma_a(), 0.032, 1e-13));
    CHECK(Dipole<double>::from_albedo(0.0, 2.0, 1.3).sigma_tr() == doctest::Approx(0.5).epsilon(1e-15));
}

TEST_CASE("bad input raises std::invalid_argument naming the value and the range") {
    auto message = [](auto&& f) {
        try {
            f();
        } catch (const std::invalid_argument& e) {
            return std::string(e.what());
        }
        return std::string("no exception");
    };
    const double nan = std::numeric_limits<double>::quiet_NaN();
    CHECK(message([] { Dipole<double>(-1.0, 1.0, 1.3); }).find("sigma_a = -1 is outside the allowed range [0, inf)") !=
          std::string::npos);
    CHECK(message([] { Dipole<double>(1.0, -0.5, 1.3); }).find("sigma_s_prime = -0.5") != std::string::npos);
    CHECK(message([&] { Dipole<double>(nan, 1.0, 1.3); }).find("sigma_a = nan") != std::string::npos);
    CHECK(message([] { Dipole<double>(0.0, 0.0, 1.3); }).find("sigma_a + sigma_s_prime = 0") != std::string::npos);
    CHECK(message([] { Dipole<double>(1.0, 1.0, 0.9); }).find("eta = 0.9") != std::string::npos);
    CHECK_NOTHROW(Dipole<double>(1.0, 1.0, 0.9, DiffuseFresnel::exact));
    CHECK(message([] { Dipole<double>(1.0, 1.0, -1.0, DiffuseFresnel::exact); }).find("[0.0001, 10000]") != std::string::npos);
    CHECK(message([] { alpha_prime_from_reflectance(1.5, 1.3); })
              .find("Rd = 1.5 is outside the allowed range [0, 1]") != std::string::npos);
    CHECK(message([] { alpha_prime_from_reflectance(-1e-9, 1.3); }).find("Rd = -1.0000000000000001e-09") !=
          std::string::npos);
    CHECK(message([&] { alpha_prime_from_reflectance(nan, 1.3); }).find("Rd = nan") != std::string::npos);
    CHECK(message([] { total_diffuse_reflectance(1.1, 1.3); }).find("alpha_prime = 1.1") != std::string::npos);
    CHECK(message([] { Dipole<double>::from_albedo(1.0, 1.0, 1.3); }).find("alpha_prime = 1 is outside") !=
          std::string::npos);
    CHECK(message([] { Dipole<double>::from_albedo(0.5, 0.0, 1.3); }).find("diffuse_mean_free_path = 0") !=
          std::string::npos);
    CHECK(message([] { AlphaPrimeTable<double>(1.3, DiffuseFresnel::jensen_fit, 1); }).find("size = 1") !=
          std::string::npos);
    // The noexcept overloads clamp instead (documented): never NaN.
    const auto b = DipoleBoundary<double>::from_eta(1.3);
    CHECK(alpha_prime_from_reflectance(nan, b) == 0.0);
    CHECK(alpha_prime_from_reflectance(2.0, b) == 1.0);
    CHECK(total_diffuse_reflectance(nan, b) == 0.0);
}

TEST_CASE("sample_radius inverts the CDF exactly, including xi = 0 and xi -> 1") {
    // u(xi) = -1 - W_-1((xi - 1)/e) from mpmath at the exact xi (lambert_wm1_reference.txt, kind u); with
    // sigma_tr = 1 the radius is u. 4 ulp: W's own ~2 and the rounding of (1 - xi)/e.
    const auto d = Dipole<double>::from_albedo(0.5, 1.0, 1.3);  // sigma_tr = 1 / ld = 1
    REQUIRE(d.sigma_tr() == doctest::Approx(1.0).epsilon(1e-15));
    std::ifstream in(STRATUM_TEST_DATA_DIR "/lambert_wm1_reference.txt");
    std::string line;
    int count = 0;
    while (std::getline(in, line)) {
        if (line.rfind("u ", 0) != 0) continue;
        std::istringstream ss(line);
        std::string kind, xs, us;
        ss >> kind >> xs >> us;
        const double xi = std::strtod(xs.c_str(), nullptr);
        const double u = static_cast<double>(std::strtold(us.c_str(), nullptr));
        INFO("xi = " << xi);
        const double r = d.sample_radius(xi) * d.sigma_tr();
        CHECK(std::fabs(r - u) <= 4 * std::numeric_limits<double>::epsilon() * u + 1e-300);
        ++count;
    }
    CHECK(count >= 15);
    CHECK(d.sample_radius(0.0) == 0.0);
    CHECK(d.sample_radius(-1.0) == 0.0);
    CHECK(d.sample_radius(std::numeric_limits<double>::quiet_NaN()) == 0.0);
    const double top = d.sample_radius(1.0);  // clamped to 1 - eps/2: u ~ 38
    CHECK(std::isfinite(top));
    CHECK(top == d.sample_radius(1 - std::numeric_limits<double>::epsilon() / 2));
    CHECK(top > 35.0);
    CHECK(top < 45.0);
    CHECK(std::isfinite(Dipole<float>(0.5f, 1.0f, 1.3f).sample_radius(1.0f)));
}

TEST_CASE("eta outside the F_dr model's range is refused (found by fuzz_pointwise: eta = 5e120 gave R_d < 0)") {
    // The Jensen fit exceeds 1 beyond eta ~ 3.8 (A < 0, so z_v < 0 and R_d < 0): it is accepted on [1, 3] only.
    CHECK(stratum::fresnel_diffuse_reflectance_fit(3.9) > 1.0);
    CHECK_THROWS_WITH_AS(DipoleBoundary<double>::from_eta(3.5), doctest::Contains("[1, 3]"), std::invalid_argument);
    CHECK_THROWS_WITH_AS(Dipole<double>(18.66, 1e-6, 5.1e120), doctest::Contains("eta"), std::invalid_argument);
    CHECK_THROWS_AS(DipoleBoundary<double>::from_eta(2e4, DiffuseFresnel::exact), std::invalid_argument);
    CHECK_NOTHROW(DipoleBoundary<double>::from_eta(3.0));
    const auto far = DipoleBoundary<double>::from_eta(1e4, DiffuseFresnel::exact);
    CHECK(std::isfinite(far.A));
    CHECK(far.A > 1);
    const Dipole<double> d(18.66, 1e-6, far);
    CHECK(d.Rd(1e-9) >= 0.0);
    CHECK(std::isfinite(d.Rd(1e-9)));
}

TEST_CASE("pdf_radius stays finite for extreme coefficients (found by fuzz_pointwise)") {
    // sigma_a = 2.8e154 gives sigma_tr = 4.9e154, whose square overflows: sigma_tr^2 r e^{-sigma_tr r} was inf * 0.
    const stratum::Dipole<double> d(2.8059504291138784e154, 1e-6, 2.5);
    CHECK(d.pdf_radius(1e-9) == 0.0);
    CHECK(d.pdf_radius(1e-160) > 0.0);  // u = sigma_tr r ~ 5e-6: sigma_tr u e^{-u} ~ 2e149
    CHECK(std::isfinite(d.pdf_radius(1e-160)));
    // sigma_tr = 2.9e116 at r = 9.8e237: u = sigma_tr r overflows, and u e^{-u} was inf * 0 = NaN.
    const stratum::Dipole<double> e(1e-6, 2.8730586208123298e238, 1.1062296839689769);
    CHECK(e.pdf_radius(9.837552273994947e237) == 0.0);
    CHECK(e.Rd(9.837552273994947e237) == 0.0);  // the same overflow in the poles' (x + 1) e^{-x}
    CHECK(e.Rd(1e100) == 0.0);
    const stratum::Dipole<double> skin(0.032, 0.74, 1.3);
    const double st = skin.sigma_tr(), r = 0.7;
    CHECK(skin.pdf_radius(r) == doctest::Approx(st * st * r * std::exp(-st * r)).epsilon(1e-15));
}

TEST_CASE("R_d is 0 without scattering, and finite where a pole alone overflows (found by review)") {
    // alpha' = 0 makes the prefactor 0; at r = 0 the poles' 1 / z^2 overflow (z_r = 1e-20 in float), and 0 x inf
    // was NaN.
    CHECK(stratum::Dipole<float>(1e20f, 0.0f, 1.3f).Rd(0.0f) == 0.0f);
    CHECK(stratum::Dipole<float>(1e20f, 0.0f, 1.3f).Rd(1e-30f) == 0.0f);
    CHECK(stratum::Dipole<double>::from_albedo(0.0, 1e-300, 1.3).Rd(0.0) == 0.0);
    CHECK(stratum::Dipole<double>(1.0, 0.0, 1.3).Rd(0.5) == 0.0);
    CHECK(stratum::Dipole<double>(1.0, 1e-300, 1.3).Rd(0.5) >= 0.0);
    // A tiny alpha' > 0: the result is representable although 1 / z_r^3 is not (float: 1e60); it was inf. Against
    // the formula in long double from the dipole's own parameters.
    const auto formula = [](const auto& d, long double r) {
        const long double st = d.sigma_tr();
        long double sum = 0;
        for (const long double z : {static_cast<long double>(d.z_r()), static_cast<long double>(d.z_v())}) {
            const long double dist = std::sqrt(r * r + z * z), x = st * dist;
            sum += z * (x + 1) * std::exp(-x) / (dist * dist * dist);
        }
        return static_cast<long double>(d.alpha_prime()) / (4 * 3.14159265358979323846L) * sum;
    };
    const stratum::Dipole<float> dense(1e20f, 1e-10f, 1.3f);
    for (const float r : {0.0f, 1e-21f, 1e-20f}) {
        CAPTURE(r);
        const float got = dense.Rd(r);
        REQUIRE(std::isfinite(got));
        CHECK(std::fabs(got - formula(dense, r)) <= 1e-6L * formula(dense, r));  // (measured 1.5e-7: 1.3 float eps)
    }
}

TEST_CASE("sample_radius follows pdf_radius (chi-square, 60 bins)") {
    // 300000 radii from a fixed-seed mt19937_64 (own [0,1) mapping); 59 equal-width bins on [0, 12/sigma_tr) plus
    // a tail bin. Expected counts from integrating pdf_radius over each bin with 16-point Gauss-Legendre (the
    // pdf is smooth: exact to ~1e-15), the tail as 1 - the rest. Critical chi^2 for 59 dof at p = 0.001: 98.3.
    const Dipole<double> d(0.032, 0.74, 1.3);  // skin1 red: sigma_tr ~ 0.28 / mm
    const double scale = 12 / d.sigma_tr();
    const int bins = 60, n = 300000;
    std::vector<double> observed(bins, 0), expected(bins, 0);
    std::mt19937_64 rng(12345);
    for (int i = 0; i < n; ++i) {
        const double xi = static_cast<double>(rng() >> 11) * 0x1.0p-53;
        const double r = d.sample_radius(xi);
        REQUIRE(r >= 0);
        const int b = r < scale ? static_cast<int>(r / scale * (bins - 1)) : bins - 1;
        observed[static_cast<std::size_t>(std::min(b, bins - 1))] += 1;
    }
    const auto rule = stratum::gauss_legendre<double>(16);
    double total = 0;
    for (int b = 0; b < bins - 1; ++b) {
        const double lo = scale * b / (bins - 1), hi = scale * (b + 1) / (bins - 1);
        double p = 0;
        for (std::size_t i = 0; i < rule.size(); ++i)
            p += rule.weights[i] * (hi - lo) / 2 * d.pdf_radius((lo + hi) / 2 + (hi - lo) / 2 * rule.nodes[i]);
        expected[static_cast<std::size_t>(b)] = p * n;
        total += p;
    }
    expected[bins - 1] = (1 - total) * n;
    double chi2 = 0;
    for (int b = 0; b < bins; ++b) {
        const auto i = static_cast<std::size_t>(b);
        chi2 += (observed[i] - expected[i]) * (observed[i] - expected[i]) / expected[i];
    }
    MESSAGE("sample_radius chi^2 = " << chi2 << " (59 dof)");
    CHECK(chi2 < 98.3);
    // And pdf_radius integrates to 1 (the last bin's share is e^{-12}(13) = 8e-5 of it).
    CHECK(std::fabs(total + 13 * std::exp(-12.0) - 1) <= 1e-12);
    CHECK(d.pdf_radius(-1.0) == 0.0);
    CHECK(d.pdf_radius(std::numeric_limits<double>::infinity()) == 0.0);
}

TEST_CASE("an RGB-of-floats call site builds one dipole per channel") {
    // Jensen et al. 2001, Table (Skin1): sigma_s' = (0.74, 0.88, 1.01), sigma_a = (0.032, 0.17, 0.48) in 1/mm.
    const auto skin = stratum::make_dipoles<float, 3>({0.032f, 0.17f, 0.48f}, {0.74f, 0.88f, 1.01f}, 1.3f);
    const std::array<float, 3> sa{0.032f, 0.17f, 0.48f}, ss{0.74f, 0.88f, 1.01f};
    for (std::size_t c = 0; c < 3; ++c) {
        const Dipole<float> one(sa[c], ss[c], 1.3f);
        CHECK(skin[c].Rd(0.5f) == one.Rd(0.5f));
        CHECK(skin[c].total_reflectance() == one.total_reflectance());
        // float agrees with double to float precision.
        const Dipole<double> dd(double(sa[c]), double(ss[c]), 1.3);
        CHECK(std::fabs(double(one.total_reflectance()) - dd.total_reflectance()) <= 4e-7 * dd.total_reflectance());
        const Dipole<long double> dl(sa[c], ss[c], 1.3L);
        CHECK(std::fabs(static_cast<double>(dl.Rd(0.5L)) - dd.Rd(0.5)) <= 1e-14 * dd.Rd(0.5));
    }
    // Skin reflects more red than blue.
    CHECK(skin[0].total_reflectance() > skin[1].total_reflectance());
    CHECK(skin[1].total_reflectance() > skin[2].total_reflectance());
}

TEST_CASE("the inversion works in float and long double") {
    // float: alpha' in float carries ~6e-8 of rounding, the float A (and hence R_d) another ~1e-7 through the
    // slope dalpha'/dR_d (<= 11); measured 1.9e-7, tolerance 1e-6. long double against double: limited by the
    // double reference, 3e-16 (measured 2.7e-16); tolerance 1e-15.
    const auto bd = DipoleBoundary<double>::from_eta(1.3);
    const auto bf = DipoleBoundary<float>::from_eta(1.3f);
    const auto bl = DipoleBoundary<long double>::from_eta(1.3L);
    double worst_f = 0, worst_l = 0;
    for (int i = 0; i <= 20000; ++i) {
        const float rf = static_cast<float>(i) / 20000.0f;
        const double a = alpha_prime_from_reflectance(double(rf), bd);
        worst_f = std::fmax(worst_f, std::fabs(double(alpha_prime_from_reflectance(rf, bf)) - a));
        worst_l = std::fmax(worst_l, static_cast<double>(std::fabs(
                                         alpha_prime_from_reflectance(static_cast<long double>(rf), bl) - a)));
    }
    CHECK(worst_f <= 1e-6);
    CHECK(worst_l <= 1e-15);
}

TEST_CASE("the inversion converges for every A the exact F_dr gives (eta up to 1e4; found by review)") {
    // With A large (k s >> 1 at the rational start) Halley's steps shrank s by ~10% each and the 12 allowed left
    // R_d 0.37 off at eta = 1e4 (A = 3.8e11, double) and 0.5 at eta 360 in float; Newton's step is taken there now.
    // R_d -> Dipole -> total_reflectance: measured within 2.2e-16 in double and 6.0e-8 in float (its A, R_d and
    // the coefficients each rounded); bounds 4 eps and 4 eps.
    std::vector<double> rds;
    for (int i = 1; i < 200; ++i) rds.push_back(i / 200.0);
    for (int e = 3; e <= 14; ++e) rds.push_back(1 - std::pow(10.0, -e / 2.0));
    double worst_d = 0, worst_f = 0;
    for (const double eta : {30.0, 100.0, 300.0, 1000.0, 2000.0, 5000.0, 1e4}) {
        for (const double rd : rds) {
            const double got = Dipole<double>::from_reflectance(rd, 1.0, eta, DiffuseFresnel::exact).total_reflectance();
            worst_d = std::fmax(worst_d, std::fabs(got - rd));
            const float rf = static_cast<float>(rd);
            if (!(rf < 1.0f)) continue;
            const float gf = Dipole<float>::from_reflectance(rf, 1.0f, static_cast<float>(eta), DiffuseFresnel::exact)
                                 .total_reflectance();
            worst_f = std::fmax(worst_f, static_cast<double>(std::fabs(gf - rf)));
        }
    }
    MESSAGE("R_d round trip at large A: double " << worst_d << ", float " << worst_f);
    CHECK(worst_d <= 4 * std::numeric_limits<double>::epsilon());
    CHECK(worst_f <= 4 * std::numeric_limits<float>::epsilon());
}

TEST_CASE("from_reflectance keeps sigma_a accurate as Rd -> 1, where alpha' cannot resolve 1 - alpha'") {
    // For Rd = 1 - d, 1 - alpha' ~ d^2 is far below the spacing of doubles near 1, but s = sigma_tr / sigma_t'
    // is carried separately. Check: the closed form evaluated at the dipole's own s, as 1 - R_d in long double
    // with expm1 (no cancellation), reproduces 1 - Rd = d to 1e-13 relative (1 - R_d ~ (k + 2) s / 2 near
    // s = 0, so this is s's relative accuracy); and sigma_tr = 1 / ld.
    const auto b = DipoleBoundary<double>::from_eta(1.3);
    const long double k = 4.0L / 3 * b.A;
    for (double d : {1e-3, 1e-6, 1e-9, 1e-12}) {
        const auto dip = Dipole<double>::from_reflectance(1 - d, 2.0, 1.3);
        const long double s = static_cast<long double>(dip.sigma_tr()) / dip.sigma_t_prime();
        const long double m1 = std::expm1(-s), m2 = std::expm1(-(k + 1) * s);
        const long double one_minus_R = -(m1 + m2) / 2 + s * s / 3 * (2 + m1 + m2) / 2;
        INFO("d = " << d);
        const double t = 1 - (1 - d);  // 1 - Rd for the double Rd = 1 - d (exact)
        CHECK(std::fabs(one_minus_R / t - 1) <= 1e-13L);
        CHECK(stratum_test::close_rel(dip.sigma_tr(), 0.5, 1e-15));
        CHECK(stratum_test::close_rel(dip.sigma_a(), dip.sigma_t_prime() * static_cast<double>(s * s / 3), 1e-14));
    }
}

TEST_CASE("Dipole<float>: the total reflectance is the profile's integral near alpha' = 1 (found by review)") {
    // The total came from alpha', whose 1 - alpha' float does not resolve near 1: at sigma_a 1e-7, sigma_s' 1 it was
    // 0.998366 where the profile integrates to 0.998504 (double's total), 10% of 1 - R_d. Now from s, as sigma_tr.
    for (float sigma_a : {1e-6f, 1e-7f, 1e-5f}) {
        const Dipole<float> f(sigma_a, 1.0f, 1.3f);
        const Dipole<double> d(sigma_a, 1.0, 1.3);
        CAPTURE(sigma_a);
        CHECK(static_cast<double>(f.total_reflectance()) == doctest::Approx(d.total_reflectance()).epsilon(1e-6));
    }
}

TEST_CASE("Dipole: a boundary given as numbers and Hery's parameters are validated (found by review)") {
    // DipoleBoundary is an aggregate: A = -5 gave a total reflectance of 9.04, A = NaN a NaN one and a NaN table.
    CHECK_THROWS_WITH_AS(Dipole<double>(0.1, 1.0, DipoleBoundary<double>{1.3, -5.0}), doctest::Contains("boundary.A"),
                         std::invalid_argument);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_AS(Dipole<double>(0.1, 1.0, DipoleBoundary<double>{1.3, nan}), std::invalid_argument);
    CHECK_THROWS_AS(Dipole<double>(0.1, 1.0, DipoleBoundary<double>{nan, 2.0}), std::invalid_argument);
    CHECK_THROWS_AS(AlphaPrimeTable<double>(DipoleBoundary<double>{1.3, 0.5}), std::invalid_argument);
    CHECK_THROWS_AS(Dipole<double>::from_albedo(0.5, 1.0, DipoleBoundary<double>{1.3, nan}), std::invalid_argument);
    CHECK_NOTHROW(Dipole<double>(0.1, 1.0, DipoleBoundary<double>{1.0, 1.0}));  // index matched: A = 1
    // F_dr within 1e-6 of 1 (float, exact model, eta 1000): A computed in double, finite (3.79e8), not +inf, whose
    // total reflectance without absorption was NaN (1 it is), whose inversion of R_d = 1e-6 gave alpha' = 1 (1.13e-5)
    // and whose table was NaN with max_error() 0 (found by review). +inf itself is refused.
    const auto dense = DipoleBoundary<float>::from_eta(1000.0f, DiffuseFresnel::exact);
    CHECK(dense.A == doctest::Approx(static_cast<float>(DipoleBoundary<double>::from_eta(1000.0, DiffuseFresnel::exact).A)).epsilon(1e-6));
    CHECK(Dipole<float>(0.0f, 1.0f, dense).total_reflectance() == 1.0f);
    CHECK(std::isfinite(Dipole<float>(0.1f, 1.0f, dense).Rd(0.5f)));
    CHECK(alpha_prime_from_reflectance(1e-6f, dense) == doctest::Approx(1.13044e-5).epsilon(1e-4));
    const AlphaPrimeTable<float> dense_table(dense);
    CHECK(std::isfinite(dense_table(0.25f)));
    CHECK(dense_table.max_error() > 0);
    CHECK_NOTHROW(Dipole<float>::from_reflectance(0.5f, 1.0f, 1000.0f, DiffuseFresnel::exact));
    CHECK_THROWS_WITH_AS(Dipole<float>(0.1f, 1.0f, DipoleBoundary<float>{1.3f, std::numeric_limits<float>::infinity()}),
                         doctest::Contains("boundary.A"), std::invalid_argument);
    // A subnormal diffuse mean free path made sigma_t' = inf (refused by the coefficients' constructor), and R_d(r)
    // was 0 everywhere while total_reflectance() said 0.30.
    CHECK_THROWS_WITH_AS(Dipole<double>::from_albedo(0.5, 1e-310, 1.3), doctest::Contains("diffuse_mean_free_path"),
                         std::invalid_argument);
    CHECK_THROWS_WITH_AS(Dipole<double>::from_reflectance(0.5, 1e-310, 1.3), doctest::Contains("diffuse_mean_free_path"),
                         std::invalid_argument);
    CHECK_NOTHROW(Dipole<double>::from_albedo(0.5, 1e-300, 1.3));
}
