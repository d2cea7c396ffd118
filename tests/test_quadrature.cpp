// Gauss-Legendre rules: ulp accuracy against high-precision references, polynomial exactness,
// symmetry, weight sums, the smallest half-range ordinate, and bad input.
#include <doctest/doctest.h>

#include <stratum/quadrature.hpp>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "test_util.hpp"

using stratum::gauss_legendre;
using stratum::gauss_legendre_half;
using stratum_test::ulp_distance;

namespace {

// One node of tests/data/gauss_legendre_reference.txt: index i (x >= 0) in the ascending n-point rule,
// the correctly rounded doubles of x, the weight w, lo = (1 - x)/2 and hi = (1 + x)/2.
struct RefNode {
    int i;
    double x, w, lo, hi;
};

// The references: __float128 Newton (tests/data/gen_quadrature_reference.cpp), cross-checked with mpmath
// (tests/data/check_quadrature_reference.py). All nodes for n <= 1024; for n in {2000, 5000, 10000} the
// 64 nodes at each end of the half and every 16th in between.
const std::map<int, std::vector<RefNode>>& references() {
    static const std::map<int, std::vector<RefNode>> table = [] {
        std::map<int, std::vector<RefNode>> t;
        std::ifstream in(STRATUM_TEST_DATA_DIR "/gauss_legendre_reference.txt");
        std::string line;
        std::vector<RefNode>* rows = nullptr;
        while (std::getline(in, line)) {
            if (line.empty() || line[0] == '#') continue;
            std::istringstream fields(line);
            if (line[0] == 'n') {
                std::string tag;
                int n = 0;
                fields >> tag >> n;
                rows = &t[n];
                continue;
            }
            std::string x, w, lo, hi;
            RefNode r{};
            fields >> r.i >> x >> w >> lo >> hi;
            // strtod reads C99 hex-floats exactly (std::istream does not).
            r.x = std::strtod(x.c_str(), nullptr);
            r.w = std::strtod(w.c_str(), nullptr);
            r.lo = std::strtod(lo.c_str(), nullptr);
            r.hi = std::strtod(hi.c_str(), nullptr);
            if (rows) rows->push_back(r);
        }
        return t;
    }();
    return table;
}

// Max and mean ulp distance, Boost.Math style.
struct UlpStat {
    std::int64_t max = 0;
    double sum = 0;
    long count = 0;
    void add(std::int64_t u) {
        if (u > max) max = u;
        sum += static_cast<double>(u);
        ++count;
    }
    double mean() const { return count ? sum / static_cast<double>(count) : 0; }
};

// ulp errors of the Real rules against the references, for the four quantities.
template <class Real>
struct RuleErrors {
    UlpStat nodes, weights, half_nodes, half_weights;
};

template <class Real>
void accumulate_errors(int n, const std::vector<RefNode>& ref, RuleErrors<Real>& e) {
    const auto full = gauss_legendre<Real>(n);
    const auto half = gauss_legendre_half<Real>(n);
    for (const RefNode& r : ref) {
        const auto i = static_cast<std::size_t>(r.i), m = static_cast<std::size_t>(n - 1 - r.i);
        // The correctly rounded float is the float rounding of the correctly rounded double: the
        // generator verified that no double here is a float rounding midpoint. w/2 is exact in binary.
        e.nodes.add(ulp_distance(full.nodes[i], static_cast<Real>(r.x)));
        e.nodes.add(ulp_distance(full.nodes[m], static_cast<Real>(-r.x)));
        e.weights.add(ulp_distance(full.weights[i], static_cast<Real>(r.w)));
        e.weights.add(ulp_distance(full.weights[m], static_cast<Real>(r.w)));
        e.half_nodes.add(ulp_distance(half.nodes[i], static_cast<Real>(r.hi)));
        e.half_nodes.add(ulp_distance(half.nodes[m], static_cast<Real>(r.lo)));
        e.half_weights.add(ulp_distance(half.weights[i], static_cast<Real>(r.w / 2)));
    }
}

template <class Real>
void print_errors(const char* label, const char* type, const RuleErrors<Real>& e) {
    MESSAGE(std::string(label) << " " << std::string(type)                                      //
                                << ": nodes max = " << e.nodes.max << " ulp (mean = " << e.nodes.mean()  //
                                << "), weights max = " << e.weights.max << " (mean = " << e.weights.mean()
                                << "), half nodes max = " << e.half_nodes.max << " (mean = " << e.half_nodes.mean()
                                << "), half weights max = " << e.half_weights.max
                                << " (mean = " << e.half_weights.mean() << ")");
}

// Tolerance: the computed values carry < 0.1 ulp of error before the final rounding (measured with the
// generator's report mode), so each lands on the correctly rounded value or, when the exact value lies
// within 0.1 ulp of a rounding midpoint, on its neighbour: max 1 ulp, and a mean far below 1 (a method
// off by one ulp everywhere would fail the mean). The requirement is 2 ulp (nodes) and 4 ulp (weights).
template <class Real>
void check_errors(const RuleErrors<Real>& e) {
    CHECK(e.nodes.max <= 1);
    CHECK(e.weights.max <= 1);
    CHECK(e.half_nodes.max <= 1);
    CHECK(e.half_weights.max <= 1);
    CHECK(e.nodes.mean() < 0.05);
    CHECK(e.weights.mean() < 0.05);
    CHECK(e.half_nodes.mean() < 0.05);
    CHECK(e.half_weights.mean() < 0.05);
}

template <class Real>
void check_range(const char* label, int n0, int n1) {
    RuleErrors<Real> e;
    int rules = 0;
    for (const auto& [n, ref] : references()) {
        if (n < n0 || n > n1) continue;
        accumulate_errors<Real>(n, ref, e);
        ++rules;
    }
    REQUIRE(rules > 0);  // the reference file was found and covers the range
    INFO(std::string(label));
    print_errors(label, sizeof(Real) == 4 ? "float" : "double", e);
    check_errors(e);
}

// Legendre polynomials P_0..P_m at x, in long double.
void legendre_all(int m, long double x, std::vector<long double>& p) {
    p.assign(static_cast<std::size_t>(m + 1), 0.0L);
    p[0] = 1;
    if (m >= 1) p[1] = x;
    for (int l = 1; l < m; ++l) {
        const auto u = static_cast<std::size_t>(l);
        p[u + 1] = ((2 * l + 1) * x * p[u] - l * p[u - 1]) / (l + 1);
    }
}

}  // namespace

TEST_CASE("the reference file holds every n in 1..128, a sample up to 1024 and n = 2000, 5000, 10000") {
    const auto& ref = references();
    for (int n = 1; n <= 128; ++n) {
        REQUIRE(ref.count(n) == 1);
        CHECK(ref.at(n).size() == static_cast<std::size_t>((n + 1) / 2));
    }
    for (int n : {150, 199, 200, 256, 300, 333, 400, 500, 512, 600, 700, 800, 900, 999, 1000, 1024})
        CHECK(ref.at(n).size() == static_cast<std::size_t>((n + 1) / 2));
    for (int n : {2000, 5000, 10000}) CHECK(ref.count(n) == 1);
}

TEST_CASE("double rules are within 1 ulp of the correctly rounded nodes and weights") {
    const int cross = stratum::detail::gauss_legendre_newton_max_n;
    check_range<double>("n = 1..128 (Newton)", 1, 128);
    check_range<double>("n = 150..200 (Newton)", 129, cross);
    check_range<double>("n = 201..1024 (asymptotic)", cross + 1, 1024);
    check_range<double>("n = 2000, 5000, 10000 (asymptotic)", 1025, 10000);
}

TEST_CASE("float rules are within 1 ulp of the correctly rounded nodes and weights") {
    check_range<float>("n = 1..1024", 1, 1024);
    check_range<float>("n = 2000, 5000, 10000", 1025, 10000);
}

TEST_CASE("long double rules are at least as accurate as the correctly rounded double") {
    // The long double values may lie anywhere within the double's rounding interval: rounded to double
    // they must be within 1 ulp of the reference (a value off by more than 1/2 ulp of double fails).
    for (int n : {1, 2, 7, 64, 200, 256, 1000, 10000}) {
        const auto full = gauss_legendre<long double>(n);
        const auto half = gauss_legendre_half<long double>(n);
        for (const RefNode& r : references().at(n)) {
            const auto i = static_cast<std::size_t>(r.i), m = static_cast<std::size_t>(n - 1 - r.i);
            CHECK(ulp_distance(static_cast<double>(full.nodes[i]), r.x) <= 1);
            CHECK(ulp_distance(static_cast<double>(full.weights[i]), r.w) <= 1);
            CHECK(ulp_distance(static_cast<double>(half.nodes[m]), r.lo) <= 1);
            CHECK(ulp_distance(static_cast<double>(half.nodes[i]), r.hi) <= 1);
        }
    }
}

TEST_CASE("every rule with n in 1..1000 is ascending, antisymmetric and sums to 2") {
    // The references store all n <= 128 and a sample above (the generator's report mode checks every n
    // against __float128). For every n up to 1000 check what needs no reference: nodes strictly
    // ascending inside (-1, 1), exact antisymmetry, and the weight sum within 2 ulp of 2 (each weight is
    // within 1 ulp, relative error <= 2^-52, so the n weights sum to within 2 * 2^-52 * 2 of 2; the sum
    // is taken in long double).
    for (int n = 1; n <= 1000; ++n) {
        const auto q = gauss_legendre<double>(n);
        REQUIRE(q.size() == static_cast<std::size_t>(n));
        long double sum = 0;
        bool ascending = true, antisymmetric = true;
        for (std::size_t i = 0; i < q.size(); ++i) {
            sum += q.weights[i];
            if (i > 0 && !(q.nodes[i] > q.nodes[i - 1])) ascending = false;
            if (q.nodes[i] != -q.nodes[q.size() - 1 - i] || q.weights[i] != q.weights[q.size() - 1 - i])
                antisymmetric = false;
        }
        INFO("n = " << n);
        CHECK(ascending);
        CHECK(antisymmetric);
        CHECK(q.nodes.front() > -1.0);
        CHECK(std::fabs(sum - 2.0L) <= 2 * std::ldexp(2.0L, -52));
    }
}

TEST_CASE("very large rules (n = 1e5, 1e6) stay ascending inside (-1, 1) with weights summing to 2") {
    // Beyond the references: the asymptotic formulas must stay finite and ordered. Sum tolerance as in
    // the test below, with n * 2^-64 of long double summation noise added.
    for (int n : {100000, 1000000}) {
        INFO("n = " << n);
        const auto q = gauss_legendre_half<double>(n);
        long double sum = 0;
        bool ascending = true;
        for (std::size_t i = 0; i < q.size(); ++i) {
            sum += q.weights[i];
            if (i > 0 && !(q.nodes[i] > q.nodes[i - 1])) ascending = false;
        }
        CHECK(ascending);
        CHECK(q.nodes.front() > 0.0);
        CHECK(q.nodes.back() < 1.0);
        CHECK(std::fabs(sum - 1) <= 2 * std::ldexp(1.0L, -52) + n * std::ldexp(1.0L, -64));
    }
}

TEST_CASE("weights sum to 2 on [-1, 1] and to 1 on [0, 1]") {
    // Each weight is within 1 ulp (relative 2^-52 for double, 2^-23 for float): the exact sum of the
    // rounded weights is within 2^-52 * 2 of 2 (resp. 2^-52 of 1); summing in long double/double adds
    // nothing visible at that scale for n <= 10000. Twice that bound as tolerance.
    for (int n : {1, 2, 3, 4, 5, 8, 16, 33, 128, 200, 201, 512, 1000, 4096, 10000}) {
        INFO("n = " << n);
        long double sd = 0, sh = 0;
        double sf = 0, sfh = 0;
        for (double w : gauss_legendre<double>(n).weights) sd += w;
        for (double w : gauss_legendre_half<double>(n).weights) sh += w;
        for (float w : gauss_legendre<float>(n).weights) sf += w;
        for (float w : gauss_legendre_half<float>(n).weights) sfh += w;
        CHECK(std::fabs(sd - 2) <= 4 * std::ldexp(1.0L, -52));
        CHECK(std::fabs(sh - 1) <= 2 * std::ldexp(1.0L, -52));
        CHECK(std::fabs(sf - 2) <= 4 * std::ldexp(1.0, -23));
        CHECK(std::fabs(sfh - 1) <= 2 * std::ldexp(1.0, -23));
    }
}

TEST_CASE("nodes are ascending and exactly antisymmetric, half-range nodes pair to 1") {
    for (int n : {1, 2, 3, 6, 7, 127, 200, 201, 202, 999, 10000}) {
        INFO("n = " << n);
        const auto q = gauss_legendre<double>(n);
        const auto h = gauss_legendre_half<double>(n);
        const auto qf = gauss_legendre<float>(n);
        const std::size_t s = q.size();
        for (std::size_t i = 0; i < s; ++i) {
            CHECK(q.nodes[i] == -q.nodes[s - 1 - i]);
            CHECK(qf.nodes[i] == -qf.nodes[s - 1 - i]);
            CHECK(q.weights[i] == q.weights[s - 1 - i]);
            CHECK(h.weights[i] == q.weights[i] / 2);
            // lo + hi = 1 before rounding; each rounding moves the sum by at most ulp(hi)/2 + ulp(lo)/2.
            CHECK(std::fabs(h.nodes[i] + h.nodes[s - 1 - i] - 1.0) <= std::numeric_limits<double>::epsilon());
            if (i > 0) {
                CHECK(q.nodes[i] > q.nodes[i - 1]);
                CHECK(h.nodes[i] > h.nodes[i - 1]);
            }
        }
        CHECK(h.nodes.front() > 0.0);
        CHECK(h.nodes.back() < 1.0);
        if (n % 2 == 1) {
            CHECK(q.nodes[s / 2] == 0.0);
            CHECK(h.nodes[s / 2] == 0.5);
        }
    }
}

TEST_CASE("the rule integrates Legendre polynomials of degree <= 2n - 1 exactly, and not degree 2n") {
    // int_{-1}^{1} P_m = 2 [m = 0]. The double rule is the exact rule with each node and weight rounded,
    // so its result may differ from the exact integral by the first-order effect of that rounding,
    //     bound_m = sum_i w_i (|P_m'(x_i)| ulp(x_i) + |P_m(x_i)| ulp(w_i) / w_i),
    // computed alongside (P_m' from P_{m-1}, P_m), plus long double summation noise. Degree 2n must fail:
    // the Gauss rule's error for P_{2n} is far above the bound.
    std::vector<long double> p;
    for (int n : {1, 2, 3, 4, 5, 8, 13, 32, 64, 128, 200, 201, 300}) {
        INFO("n = " << n);
        const auto q = gauss_legendre<double>(n);
        const int mmax = 2 * n;
        std::vector<long double> sum(static_cast<std::size_t>(mmax + 1), 0.0L), bound(sum);
        for (std::size_t i = 0; i < q.size(); ++i) {
            const long double x = q.nodes[i], w = q.weights[i];
            legendre_all(mmax, x, p);
            const long double ux = std::nextafter(std::fabs(q.nodes[i]), 2.0) - std::fabs(q.nodes[i]);
            const long double uw = std::nextafter(q.weights[i], 4.0) - q.weights[i];
            for (int m = 0; m <= mmax; ++m) {
                const auto u = static_cast<std::size_t>(m);
                // P_m'(x) = m (x P_m - P_{m-1}) / (x^2 - 1), bounded by m(m+1)/2 at |x| <= 1.
                long double dp = 0;
                if (m > 0) dp = std::fabs(m * (x * p[u] - p[u - 1]) / (x * x - 1));
                if (m > 0) dp = std::fmin(dp, 0.5L * m * (m + 1));
                sum[u] += w * p[u];
                bound[u] += w * dp * ux + std::fabs(p[u]) * uw;
            }
        }
        for (int m = 0; m < mmax; ++m) {
            const auto u = static_cast<std::size_t>(m);
            const long double exact = m == 0 ? 2 : 0;
            const long double tol = bound[u] + 64 * std::numeric_limits<long double>::epsilon();
            INFO("m = " << m);
            CHECK(std::fabs(sum[u] - exact) <= tol);
        }
        const auto u2n = static_cast<std::size_t>(mmax);
        CHECK(std::fabs(sum[u2n]) > 1000 * (bound[u2n] + 64 * std::numeric_limits<long double>::epsilon()));
    }
}

TEST_CASE("the half-range rule integrates monomials of degree <= 2n - 1 on [0, 1]") {
    // int_0^1 mu^m = 1/(m + 1). Rounding each ordinate to relative 2^-53 changes mu^m by m 2^-53 and each
    // weight by 2^-53: relative bound (m + 1) 2^-53 on a sum of positive terms, plus summation noise
    // (long double for double, double for float). Twice that bound.
    for (int n : {1, 2, 5, 16, 64, 201, 1000}) {
        INFO("n = " << n);
        const auto h = gauss_legendre_half<double>(n);
        const auto hf = gauss_legendre_half<float>(n);
        for (int m = 0; m <= 2 * n - 1; ++m) {
            long double s = 0;
            double sf = 0;
            for (std::size_t i = 0; i < h.size(); ++i) {
                s += h.weights[i] * std::pow(static_cast<long double>(h.nodes[i]), m);
                sf += static_cast<double>(hf.weights[i]) * std::pow(static_cast<double>(hf.nodes[i]), m);
            }
            const long double exact = 1.0L / (m + 1);
            INFO("m = " << m);
            CHECK(std::fabs(s - exact) <= 2 * (m + 2) * std::ldexp(1.0L, -53) * exact);
            CHECK(std::fabs(sf - static_cast<double>(exact)) <= 2 * (m + 2) * std::ldexp(1.0, -24) * exact);
        }
    }
}

TEST_CASE("the smallest half-range ordinate keeps full relative accuracy") {
    // mu_0 = (1 + x_0)/2 ~ 1.45 / (n + 1/2)^2 is sin^2(theta/2) of the unrounded root: within 1 ulp of the
    // reference. Mapping the rounded double node instead loses everything but ~-log2(mu_0) bits: this
    // shows the reference discriminates (the naive map is off by far more than 1000 ulp at n = 10000).
    for (int n : {128, 1000, 10000}) {
        INFO("n = " << n);
        const RefNode& outer = references().at(n).back();  // i = n - 1: x nearest 1
        REQUIRE(outer.i == n - 1);
        const auto h = gauss_legendre_half<double>(n);
        const auto q = gauss_legendre<double>(n);
        CHECK(ulp_distance(h.nodes.front(), outer.lo) <= 1);
        CHECK(ulp_distance(h.nodes.back(), outer.hi) <= 1);
        CHECK(ulp_distance(static_cast<double>(gauss_legendre_half<float>(n).nodes.front()),
                           static_cast<double>(static_cast<float>(outer.lo))) <= 1);
        if (n == 10000) CHECK(ulp_distance((1 + q.nodes.front()) / 2, outer.lo) > 1000);
    }
}

TEST_CASE("Newton and the asymptotic expansion agree where they meet") {
    // Both are accurate to < 0.1 ulp of double above n = 200 (measured); below, the expansion's O(v^8)
    // truncation error grows. At n = 201..205 they agree to well within 1 ulp of double.
    for (int n = 201; n <= 205; ++n) {
        for (int k = 1; k <= (n + 1) / 2; ++k) {
            const auto a = stratum::detail::gauss_legendre_node_newton(n, k);
            const auto b = stratum::detail::gauss_legendre_node_asymptotic(n, k);
            INFO("n = " << n << ", k = " << k);
            CHECK(std::fabs(a.x - b.x) <= 0.1L * std::numeric_limits<double>::epsilon() * std::fmax(a.x, 0.01L));
            CHECK(std::fabs(a.weight - b.weight) <= 0.1L * std::numeric_limits<double>::epsilon() * a.weight);
            CHECK(std::fabs(a.lo - b.lo) <= 0.1L * std::numeric_limits<double>::epsilon() * a.lo);
        }
    }
}

TEST_CASE("n < 1 throws std::invalid_argument naming n") {
    CHECK_THROWS_AS(gauss_legendre<double>(0), std::invalid_argument);
    CHECK_THROWS_AS(gauss_legendre_half<float>(-3), std::invalid_argument);
    CHECK_THROWS_WITH(gauss_legendre<double>(0), doctest::Contains("n = 0"));
    CHECK_THROWS_WITH(gauss_legendre_half<double>(-5), doctest::Contains("n = -5"));
}
