// detail/math.hpp: the thread-safe log-gamma family, against glibc's lgamma (called here single-threaded) and
// against the three-lgamma form of the Beta function that the interface used before.
#include <doctest/doctest.h>

#include <stratum/detail/math.hpp>
#include <stratum/interface.hpp>
#include <stratum/quadrature.hpp>

#include <cmath>
#include <algorithm>
#include <cstdint>
#include <limits>
#include <vector>

#include "reference/rough_albedo_reference.hpp"
#include "test_util.hpp"

using stratum::Shadowing;
using stratum::detail::log_beta1;
using stratum::detail::log_gamma;
using stratum_test::ulp_distance;

namespace {

// x in [1, 1e6]: 20 000 log-spaced points plus the ends of the methods' ranges and the zeros' neighbourhoods.
std::vector<double> log_gamma_arguments() {
    std::vector<double> xs;
    for (int i = 0; i <= 20000; ++i) xs.push_back(std::pow(10.0, 6.0 * i / 20000));
    for (double x : {1.0, 2.0, 1.5, 2.5, 10.0, 3.0, 9.5, 1e6}) {
        double lo = x, hi = x;
        for (int k = 0; k < 4; ++k) {
            xs.push_back(lo);
            xs.push_back(hi);
            lo = std::nextafter(lo, 0.0);
            hi = std::nextafter(hi, 2e6);
        }
    }
    for (double d : {1e-15, 1e-12, 1e-9, 1e-6, 1e-3}) {
        xs.push_back(1 + d);
        xs.push_back(2 - d);
        xs.push_back(2 + d);
    }
    return xs;
}

// The previous implementation of B(1 + a, 1 + b), three glibc lgammas.
double beta_three_lgamma(double a, double b) {
    return std::exp(std::lgamma(1 + a) + std::lgamma(1 + b) - std::lgamma(2 + a + b));
}

}  // namespace

TEST_CASE("log_gamma agrees with glibc's lgamma on [1, 1e6] to a few ulp of the result") {
    // Relative error in ulp of the result where |lnGamma| >= 0.5; near the zeros x = 1 and x = 2 (|lnGamma| < 0.5,
    // where an ulp of the result shrinks to nothing) the absolute error.
    std::int64_t max_ulp = 0, max_ulp_near_zeros = 0;
    double max_abs_near_zeros = 0, worst_x = 0;
    for (double x : log_gamma_arguments()) {
        const double got = log_gamma(x), want = std::lgamma(x);
        INFO("x = " << x << " got " << got << " want " << want);
        if (std::fabs(want) >= 0.5) {
            const std::int64_t d = ulp_distance(got, want);
            if (d > max_ulp) {
                max_ulp = d;
                worst_x = x;
            }
            CHECK(d <= 3);
        } else {
            // 2.5e-16: two ulp of numbers in [0.25, 0.5)
            max_abs_near_zeros = std::fmax(max_abs_near_zeros, std::fabs(got - want));
            max_ulp_near_zeros = std::max(max_ulp_near_zeros, ulp_distance(got, want));
            CHECK(std::fabs(got - want) <= 2.5e-16);
        }
    }
    MESSAGE("log_gamma vs lgamma: max " << max_ulp << " ulp (at x = " << worst_x << "), max absolute error "
                                       << max_abs_near_zeros << " (" << max_ulp_near_zeros
                                       << " ulp) where |lnGamma| < 0.5");
    CHECK(log_gamma(1.0) == 0.0);
    CHECK(log_gamma(2.0) == 0.0);
    CHECK(log_gamma(std::numeric_limits<double>::infinity()) == std::numeric_limits<double>::infinity());
    CHECK(std::isnan(log_gamma(std::numeric_limits<double>::quiet_NaN())));
    CHECK(std::isfinite(log_gamma(1e300)));
}

TEST_CASE("log_gamma<long double> agrees with lgammal") {
    double max_rel = 0;
    for (double xd : log_gamma_arguments()) {
        const long double x = xd, got = log_gamma(x), want = std::lgamma(x);
        const long double scale = std::fmax(std::fabs(want), 0.5L);
        max_rel = std::fmax(max_rel, static_cast<double>(std::fabs(got - want) / scale));
    }
    MESSAGE("log_gamma<long double> vs lgammal: max error " << max_rel << " relative (absolute where |lnGamma| < 0.5)");
    CHECK(max_rel <= 8 * static_cast<double>(std::numeric_limits<long double>::epsilon()));
}

TEST_CASE("the BTDF's Beta function agrees with the previous three-lgamma form") {
    // B(1 + a, 1 + b) for the Smith Lambdas a, b that the height-correlated transmission shadowing needs.
    // Where the old form is accurate (a, b <= 20: its three lgammas are below 60, rounding ~1e-14), the two agree
    // to 1e-14 relative; beyond, the old form loses ~eps lnGamma(2 + a + b) and the new one is checked against
    // long double lgammal instead (whose own error there is ~1e-19 lnGamma).
    const double values[] = {0.0, 1e-12, 1e-6, 1e-3, 0.01, 0.1, 0.3, 0.5, 1.0, 2.0, 3.7, 7.0, 10.0, 20.0,
                             50.0, 100.0, 1e3, 1e4, 1e5, 1e6};
    double max_old = 0, max_ld = 0;
    for (double a : values)
        for (double b : values) {
            const double got = stratum::detail::smith_g2<double>(a, b, Shadowing::height_correlated, true);
            const double g2g1 = stratum_test::smith_g2_over_g1<double>(a, b, Shadowing::height_correlated, true);
            const long double ld = std::exp(std::lgamma(1 + static_cast<long double>(a)) +
                                            std::lgamma(1 + static_cast<long double>(b)) -
                                            std::lgamma(2 + static_cast<long double>(a) + b));
            INFO("a = " << a << " b = " << b << " got " << got);
            CHECK(got == std::exp(log_beta1(a, b)));
            // G2 / G1(i) = (1 + a) B(1 + a, 1 + b)
            CHECK(g2g1 == doctest::Approx((1 + a) * got).epsilon(1e-14));
            if (a <= 20 && b <= 20) {
                // Both forms are exp of a sum of rounded logs of size up to ~60: each is off by up to 1e-14.
                const double old = beta_three_lgamma(a, b);
                max_old = std::fmax(max_old, std::fabs(got - old) / old);
                CHECK(std::fabs(got - old) <= 2e-14 * old);
            }
            if (ld > 1e-300L) {
                const double rel = static_cast<double>(std::fabs(got - ld) / ld);
                // lgammal's own error: ~1e-19 lnGamma(2 + a + b); ours: a few eps per unit of |ln B| (exp of a
                // sum of rounded logs whose terms grow with |ln B|).
                const double tol = 2e-15 * (1 + std::fabs(std::log(static_cast<double>(ld)))) +
                                   2e-19 * std::lgamma(2 + a + b);
                max_ld = std::fmax(max_ld, rel);
                CHECK(rel <= tol);
            }
        }
    MESSAGE("B(1 + a, 1 + b): max relative difference " << max_old << " from the three-lgamma form (a, b <= 20), "
                                                         << max_ld << " from the long double reference");
}

TEST_CASE("lagrange_weights reproduce polynomials of degree < p and choose the nearest stencil") {
    // Reference: a polynomial of degree p - 1 evaluated directly. Nodes: a half-range Gauss rule (uneven spacing).
    const auto q = stratum::gauss_legendre_half<double>(9);
    const int count = static_cast<int>(q.nodes.size());
    auto poly = [](double x, int degree) {
        double v = 0;
        for (int d = 0; d <= degree; ++d) v = v * x + (1.0 + 0.5 * d);
        return v;
    };
    for (int p : {1, 2, 3, 4, 6}) {
        for (double x : {0.0, 0.013, 0.2, 0.5, 0.77, 0.99, 1.0, 1.2}) {
            double w[8];
            const auto window = stratum::detail::lagrange_weights(q.nodes.data(), count, x, p, w);
            REQUIRE(window.points == p);
            REQUIRE(window.first >= 0);
            REQUIRE(window.first + window.points <= count);
            double sum = 0, value = 0;
            for (int a = 0; a < p; ++a) {
                sum += w[a];
                value += w[a] * poly(q.nodes[static_cast<std::size_t>(window.first + a)], p - 1);
            }
            INFO("p = " << p << ", x = " << x);
            CHECK(sum == doctest::Approx(1.0).epsilon(1e-12));
            CHECK(value == doctest::Approx(poly(x, p - 1)).epsilon(1e-10));
            // Inside the node range the stencil brackets x (p >= 2) as far as the ends allow.
            if (p >= 2 && x > q.nodes.front() && x < q.nodes.back()) {
                const double lo = q.nodes[static_cast<std::size_t>(window.first)];
                const double hi = q.nodes[static_cast<std::size_t>(window.first + p - 1)];
                CHECK(lo <= x);
                CHECK(x <= hi);
            }
        }
    }
    // `lowest` excludes the nodes below it (the layer's escape cone); p shrinks to what is left.
    double w[4];
    const auto window = stratum::detail::lagrange_weights(q.nodes.data(), count, 0.95, 4, w, count - 2);
    CHECK(window.first == count - 2);
    CHECK(window.points == 2);
}
