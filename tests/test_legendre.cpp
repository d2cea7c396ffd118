// Legendre polynomials and normalized associated Legendre functions: closed forms, orthogonality,
// the addition theorem, parity, the poles, and high-precision references at extreme orders.
#include <doctest/doctest.h>

#include <stratum/legendre.hpp>
#include <stratum/quadrature.hpp>

#include <cfloat>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "test_util.hpp"

using stratum::legendre_lambda;
using stratum::legendre_lambda_all;
using stratum::legendre_p;
using stratum::legendre_p_all;
using stratum_test::ulp_distance;

namespace {

const double xs_interior[] = {-0.97, -0.5, -0.1, 0.0, 0.3, 0.71, 0.999};

// v[i] with an int index (keeps -Wsign-conversion quiet without casts at every use).
template <class V>
auto at(V& v, int i) -> decltype(v[0]) {
    return v[static_cast<std::size_t>(i)];
}

}  // namespace

TEST_CASE("low-order Legendre polynomials match their closed forms") {
    // P_2..P_5 written out (Abramowitz & Stegun 22.3.8), evaluated in long double and rounded.
    for (double x : xs_interior) {
        const long double X = x, X2 = X * X;
        const long double ref[] = {1, X, (3 * X2 - 1) / 2, (5 * X2 - 3) * X / 2, ((35 * X2 - 30) * X2 + 3) / 8,
                                   ((63 * X2 - 70) * X2 + 15) * X / 8};
        double all[6];
        legendre_p_all(5, x, all);
        for (int l = 0; l <= 5; ++l) {
            // A few roundings in the recurrence and the closed form; near a zero of P_l relative
            // accuracy is meaningless, so the bound is 4 ulp of the largest term (|P_l| <= 1).
            const double r = static_cast<double>(ref[l]);
            CHECK(std::fabs(all[l] - r) <= 4 * DBL_EPSILON);
            CHECK(legendre_p(l, x) == all[l]);
        }
    }
}

TEST_CASE("low-order normalized associated functions match closed forms with the Condon-Shortley sign") {
    // Lambda_l^k = sqrt((l-k)!/(l+k)!) P_l^k, P_l^k = (-1)^k (1-x^2)^{k/2} d^k P_l/dx^k.
    for (double x : xs_interior) {
        const long double X = x, S = std::sqrt((1 - X) * (1 + X));
        struct Case {
            int l, k;
            long double value;
        };
        const Case cases[] = {
            {0, 0, 1},
            {1, 0, X},
            {1, 1, -S / std::sqrt(2.0L)},
            {2, 1, -3 * X * S / std::sqrt(6.0L)},
            {2, 2, 3 * S * S / std::sqrt(24.0L)},
            {3, 1, -1.5L * (5 * X * X - 1) * S / std::sqrt(12.0L)},
            {3, 2, 15 * X * S * S / std::sqrt(120.0L)},
            {3, 3, -15 * S * S * S / std::sqrt(720.0L)},
        };
        for (const Case& c : cases) {
            // 8 eps absolute: a handful of roundings in sqrt factors and products of values <= 1.
            CHECK(std::fabs(legendre_lambda(c.l, c.k, x) - static_cast<double>(c.value)) <= 8 * DBL_EPSILON);
        }
        // Order 0 is the Legendre polynomial itself (two recurrences with different rounding; both
        // values are <= 1, so the bound is absolute: 16 eps for 40 steps of a few roundings each).
        double p[41], lam0[41];
        legendre_p_all(40, x, p);
        legendre_lambda_all(0, 40, x, lam0);
        for (int l = 0; l <= 40; ++l) CHECK(std::fabs(p[l] - lam0[l]) <= 16 * DBL_EPSILON);
    }
}

TEST_CASE("normalized functions are orthogonal with norm 2/(2l+1), by Gauss quadrature") {
    // Lambda_l^k Lambda_n^k is a polynomial of degree l + n (the sin^{2k} factor is (1 - x^2)^k), so a
    // 64-point rule integrates it exactly for l + n <= 127; the error left is rounding, ~1e-15.
    const auto rule = stratum::gauss_legendre<double>(64);
    const int lmax = 63;
    for (int k : {0, 1, 2, 7, 30, 63}) {
        std::vector<std::vector<double>> values(rule.size(), std::vector<double>(lmax + 1));
        for (std::size_t i = 0; i < rule.size(); ++i) legendre_lambda_all(k, lmax, rule.nodes[i], values[i].data());
        double worst = 0;
        for (int l = k; l <= lmax; ++l)
            for (int n = k; n <= lmax; ++n) {
                double sum = 0;
                for (std::size_t i = 0; i < rule.size(); ++i) sum += rule.weights[i] * at(values[i], l) * at(values[i], n);
                const double expected = l == n ? 2.0 / (2 * l + 1) : 0.0;
                worst = std::fmax(worst, std::fabs(sum - expected));
            }
        CHECK(worst <= 2e-15);
    }
}

TEST_CASE("addition theorem: sum_k (2 - delta_k0) Lambda_l^k(x)^2 = 1 up to l = 2000, also near the poles") {
    // P_l(1) = 1 = sum over all orders; this checks every k at once at the largest degree the
    // library promises, including x at the outermost node of a 100-point rule and 1 - 2^-40.
    // Tolerance: measured worst 1.8e-14 (at x = 1 - 2^-40; 2.9e-12 before the difference form near
    // the poles); 1e-13 leaves room for other compilers' rounding.
    const int L = 2000;
    const double outermost = stratum::gauss_legendre<double>(100).nodes.back();
    std::vector<double> column(L + 1);
    for (double x : {outermost, 1 - std::ldexp(1.0, -40), -0.999, 0.5, 0.0}) {
        std::vector<double> sum(L + 1, 0.0);
        for (int k = 0; k <= L; ++k) {
            legendre_lambda_all(k, L, x, column.data());
            for (int l = k; l <= L; ++l) at(sum, l) += (k == 0 ? 1 : 2) * at(column, l) * at(column, l);
        }
        double worst = 0;
        for (int l = 0; l <= L; ++l) worst = std::fmax(worst, std::fabs(sum[static_cast<std::size_t>(l)] - 1));
        CAPTURE(x);
        CHECK(worst <= 1e-13);
    }
}

TEST_CASE("parity: Lambda_l^k(-x) = (-1)^(l+k) Lambda_l^k(x), exactly") {
    // The recurrence is odd/even in x term by term and sin(theta) is formed symmetrically, so the
    // relation holds bit for bit.
    std::vector<double> a(301), b(301);
    for (double x : {0.2, 0.9, 0.99999}) {
        for (int k : {0, 1, 4, 150}) {
            legendre_lambda_all(k, 300, x, a.data());
            legendre_lambda_all(k, 300, -x, b.data());
            bool ok = true;
            for (int l = k; l <= 300; ++l) ok = ok && at(b, l) == ((l + k) % 2 == 0 ? at(a, l) : -at(a, l));
            CHECK(ok);
        }
    }
}

TEST_CASE("at the poles x = +-1: Lambda_l^0 = (+-1)^l and Lambda_l^k = 0 for k > 0") {
    std::vector<double> v(101);
    for (double x : {1.0, -1.0}) {
        legendre_lambda_all(0, 100, x, v.data());
        for (int l = 0; l <= 100; ++l) CHECK(at(v, l) == (x < 0 && l % 2 == 1 ? -1.0 : 1.0));
        for (int k : {1, 2, 50}) {
            legendre_lambda_all(k, 100, x, v.data());
            for (int l = 0; l <= 100; ++l) CHECK(at(v, l) == 0.0);
        }
    }
}

namespace {

struct Reference {
    int l, k;
    double x;
    std::string value;  // decimal, possibly far outside the double range
};

std::vector<Reference> read_references() {
    std::ifstream in(std::string(STRATUM_TEST_DATA_DIR) + "/legendre_reference.txt");
    REQUIRE(in.good());
    std::vector<Reference> refs;
    std::string line;
    while (std::getline(in, line)) {
        if (line.empty() || line[0] == '#') continue;
        std::istringstream fields(line);
        Reference r;
        std::string x;
        fields >> r.l >> r.k >> x >> r.value;
        r.x = std::strtod(x.c_str(), nullptr);
        refs.push_back(r);
    }
    return refs;
}

// Decimal exponent of a decimal string "d.ddde-NNN" (value 0 gives a huge negative exponent).
long decimal_exponent(const std::string& s) {
    const auto e = s.find_first_of("eE");
    const double mantissa = std::strtod(s.substr(0, e).c_str(), nullptr);
    if (mantissa == 0) return -100000;
    return (e == std::string::npos ? 0 : std::strtol(s.c_str() + e + 1, nullptr, 10)) +
           static_cast<long>(std::floor(std::log10(std::fabs(mantissa))));
}

}  // namespace

TEST_CASE("extreme orders and |x| -> 1 agree with exact-arithmetic references (tests/data/gen_legendre.py)") {
    // References: the explicit Rodrigues sum in exact rational arithmetic at the binary value of x,
    // scaled in 60-digit mpmath, for l up to 2000, k up to 2000, x at the outermost node of a 100-point
    // rule (sin(theta)^200 ~ 1e-325 there), 1 - 2^-40, 0.9999, 0.5, -0.3, -0.999.
    const auto refs = read_references();
    REQUIRE(refs.size() > 100);
    int normal = 0, subnormal = 0, zero = 0;
    double worst_rel = 0, worst_rel_f = 0;
    for (const Reference& r : refs) {
        CAPTURE(r.l);
        CAPTURE(r.k);
        CAPTURE(r.x);
        const double got = legendre_lambda(r.l, r.k, r.x);
        const double expected = std::strtod(r.value.c_str(), nullptr);  // rounds, or underflows to 0
        const long exponent = decimal_exponent(r.value);
        if (std::fabs(expected) >= DBL_MIN) {
            // Relative: the recurrence loses up to ~150 ulp over ~1000 steps in the oscillatory
            // region (measured worst 3.1e-14 relative over this set). Beyond the turning point
            // (l (l + 1) sin^2 > k^2) the function oscillates and relative error is meaningless at its
            // zeros, so an absolute 1e-16 is added there (|Lambda| <= 1 by the addition theorem).
            ++normal;
            const double sin2 = (1 - r.x) * (1 + r.x);
            const bool oscillatory = double(r.l) * (r.l + 1) * sin2 > double(r.k) * r.k;
            const double err = std::fabs(got - expected);
            worst_rel = std::fmax(worst_rel, err / std::fabs(expected));
            CHECK(err <= 1e-13 * std::fabs(expected) + (oscillatory ? 1e-16 : 0.0));
        } else if (exponent >= -324) {
            // Subnormal result: one final rounding, absolute error within one subnormal step
            // plus the relative error of the mantissa.
            ++subnormal;
            CHECK(std::fabs(got - expected) <= std::numeric_limits<double>::denorm_min() + 1e-13 * std::fabs(expected));
        } else {
            ++zero;  // far below the smallest subnormal: must be exactly 0, never NaN
            CHECK(got == 0.0);
        }
        // float: the same loss in float ulp (measured worst 5.2e-6 relative), 0 far below its range.
        const float got_f = legendre_lambda(r.l, r.k, static_cast<float>(r.x));
        if (static_cast<double>(static_cast<float>(r.x)) == r.x) {
            if (std::fabs(expected) >= FLT_MIN) {
                const double sin2 = (1 - r.x) * (1 + r.x);
                const bool oscillatory = double(r.l) * (r.l + 1) * sin2 > double(r.k) * r.k;
                const double err = std::fabs(got_f - expected);
                worst_rel_f = std::fmax(worst_rel_f, err / std::fabs(expected));
                CHECK(err <= 3e-5 * std::fabs(expected) + (oscillatory ? 1e-7 : 0.0));
            }
            if (exponent < -50) CHECK(got_f == 0.0f);
        }
    }
    // The reference set must exercise all three regimes (otherwise this test proves less than it says).
    CHECK(normal > 50);
    CHECK(subnormal >= 1);
    CHECK(zero > 10);
    MESSAGE("worst relative error: double " << worst_rel << ", float " << worst_rel_f);
}

TEST_CASE("long double agrees with double and extends the range below 1e-308") {
    // Same recurrence in a wider type: double is within its own tolerance of long double, and long
    // double represents values (~1e-325 at k = 200, l = 200 at the outermost 100-point node) that
    // underflow in double.
    const long double outermost = stratum::gauss_legendre<long double>(100).nodes.back();
    const long double v = legendre_lambda(200, 200, outermost);
    CHECK(v != 0.0L);
    CHECK(std::isfinite(v));
    for (double x : {0.3, -0.8, 0.9995}) {
        for (int l : {10, 500, 2000})
            for (int k : {0, 3, 200}) {
                const long double wide = legendre_lambda(l, k, static_cast<long double>(x));
                const double narrow = legendre_lambda(l, k, x);
                if (std::fabs(wide) > 1e-300L)
                    CHECK(std::fabs(static_cast<long double>(narrow) - wide) <= 5e-14L * std::fabs(wide) + 1e-15L);
            }
    }
}
