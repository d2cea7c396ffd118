// Reference Gauss-Legendre rules in __float128 (113-bit significand) for tests/test_quadrature.cpp,
// and the accuracy report of stratum's gauss_legendre / gauss_legendre_half against them.
//
// The reference is computed independently of stratum: plain Newton's method on the three-term
// recurrence in x, entirely in __float128 (only +, -, *, / and conversions: libgcc, no libquadmath),
// started from a long double Newton solution. Near x = 1 the node carries an absolute error ~1e-34,
// so 1 - x (and so the smallest half-range ordinate and the weight) keeps a relative error ~1e-34 n^2,
// below 1e-25 for n <= 10000: far below double's 1.1e-16. Every root is checked against Bruns'
// bracket (k - 1/2) pi / (n + 1/2) < theta_k < k pi / (n + 1/2). Values are written as the correctly
// rounded double (the __float128 -> double conversion rounds to nearest even), in C99 hex-float.
// The correctly rounded float is the float rounding of that double: the generator checks that the
// double is never exactly a float rounding midpoint, the one case where double rounding could differ.
// tests/data/check_quadrature_reference.py cross-checks a sample of the file with mpmath.
//
// Build and run (from the repository root):
//   g++ -O2 -std=c++17 -o /tmp/gen_quad tests/data/gen_quadrature_reference.cpp
//   /tmp/gen_quad write > tests/data/gauss_legendre_reference.txt     # ~1 min
//   g++ -O2 -std=c++17 -DWITH_STRATUM -Iinclude -o /tmp/gen_quad tests/data/gen_quadrature_reference.cpp
//   /tmp/gen_quad report [nmax]    # ulp errors of stratum for every n in 1..nmax (default 1000)
//                                  # and n in {2000, 5000, 10000}; several minutes
//
// File format: lines "n <n> <count>", then <count> lines "i x w lo hi" for nodes i (index in the
// ascending n-point rule) with x >= 0: x = cos(theta_i), w the full-range weight, lo = (1 - x)/2 and
// hi = (1 + x)/2 the half-range ordinates at indices n-1-i and i. Half-range weights are w/2.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <algorithm>
#include <cstring>
#include <limits>
#include <type_traits>
#include <vector>

#ifdef WITH_STRATUM
#include <stratum/quadrature.hpp>
#endif

using quad = __float128;

namespace {

struct RefNode {
    quad x, w, lo, hi;
};

// P_n(x) and P_{n-1}(x) by the three-term recurrence, in type T.
template <class T>
void legendre(int n, T x, T& pn, T& pn1) {
    T p0 = 1, p1 = x;
    for (int l = 1; l < n; ++l) {
        const T p2 = ((2 * l + 1) * x * p1 - l * p0) / (l + 1);
        p0 = p1;
        p1 = p2;
    }
    pn = p1;
    pn1 = (n == 1) ? T(1) : p0;
    if (n == 1) pn = x;
}

quad qabs(quad a) { return a < 0 ? -a : a; }

// k = 1..(n+1)/2 counts the non-negative nodes from x = 1 (theta ascending).
RefNode reference_node(int n, int k) {
    const long double pi = 3.141592653589793238462643383279502884L;
    if (2 * k - 1 == n) {  // middle node of odd n: x = 0, w = 2 / P_n'(0)^2 = 2 / (n P_{n-1}(0))^2
        quad pn, pn1;
        legendre<quad>(n, 0, pn, pn1);
        const quad d = n * pn1;
        return {0, 2 / (d * d), quad(0.5), quad(0.5)};
    }
    // Initial guess (Tricomi), then long double Newton, then __float128 Newton.
    const long double t0 = pi * (k - 0.25L) / (n + 0.5L);
    long double xl = (1 - (1 - 1.0L / n) / (8.0L * n * n)) * std::cos(t0);
    for (int it = 0; it < 100; ++it) {
        long double pn, pn1;
        legendre<long double>(n, xl, pn, pn1);
        const long double dp = n * (pn1 - xl * pn) / (1 - xl * xl);
        const long double dx = pn / dp;
        xl -= dx;
        if (std::fabs(dx) < 1e-18L) break;
    }
    quad x = xl, pn = 0, pn1 = 0;
    for (int it = 0; it < 6; ++it) {
        legendre<quad>(n, x, pn, pn1);
        const quad dp = n * (pn1 - x * pn) / (1 - x * x);
        const quad dx = pn / dp;
        x -= dx;
        if (qabs(dx) < quad(1e-30)) break;
    }
    legendre<quad>(n, x, pn, pn1);
    const quad one_minus_x2 = (1 - x) * (1 + x);
    const quad dp = n * (pn1 - x * pn) / one_minus_x2;
    const quad w = 2 / (one_minus_x2 * dp * dp);
    // Bruns' bracket on theta = acos(x), checked in long double with a margin.
    const long double theta = std::acos(static_cast<long double>(x));
    if (!(theta > pi * (k - 0.5L) / (n + 0.5L) - 1e-15L && theta < pi * k / (n + 0.5L) + 1e-15L)) {
        std::fprintf(stderr, "root outside Bruns' bracket: n=%d k=%d\n", n, k);
        std::exit(1);
    }
    return {x, w, (1 - x) / 2, (1 + x) / 2};
}

// True if the double is exactly halfway between two adjacent floats (low 29 significand bits 1000...).
bool is_float_midpoint(double d) {
    std::uint64_t bits;
    std::memcpy(&bits, &d, sizeof bits);
    return (bits & ((std::uint64_t(1) << 29) - 1)) == (std::uint64_t(1) << 28);
}

double to_double_checked(quad q) {
    const double d = static_cast<double>(q);
    if (is_float_midpoint(d) || static_cast<float>(d) != static_cast<float>(q)) {
        std::fprintf(stderr, "double rounding would misround the float reference\n");
        std::exit(1);
    }
    return d;
}

// Which nodes of the non-negative half (m = 0 at the middle .. h-1 at x near 1) go into the file.
bool stored(int n, int m, int h) {
    if (n <= 1024) return true;
    return m < 64 || m >= h - 64 || m % 16 == 0;
}

void write_file() {
    std::vector<int> ns;
    for (int n = 1; n <= 128; ++n) ns.push_back(n);
    for (int n : {150, 199, 200, 256, 300, 333, 400, 500, 512, 600, 700, 800, 900, 999, 1000, 1024, 2000, 5000,
                  10000})
        ns.push_back(n);
    std::printf("# Gauss-Legendre references, generated by tests/data/gen_quadrature_reference.cpp\n");
    for (int n : ns) {
        const int h = (n + 1) / 2;
        std::vector<int> ks;
        for (int k = h; k >= 1; --k)
            if (stored(n, h - k, h)) ks.push_back(k);
        std::printf("n %d %zu\n", n, ks.size());
        for (int k : ks) {
            const RefNode r = reference_node(n, k);
            std::printf("%d %a %a %a %a\n", n - k, to_double_checked(r.x), to_double_checked(r.w),
                        to_double_checked(r.lo), to_double_checked(r.hi));
        }
    }
}

#ifdef WITH_STRATUM
// ulp distance between two finite values of the same type (monotone integer mapping of the bits).
template <class T>
std::int64_t ulps(T a, T b) {
    using Bits = std::conditional_t<sizeof(T) == 4, std::int32_t, std::int64_t>;
    auto ordered = [](T x) {
        Bits bits;
        std::memcpy(&bits, &x, sizeof bits);
        return bits < 0 ? static_cast<std::int64_t>(std::numeric_limits<Bits>::min()) - bits
                        : static_cast<std::int64_t>(bits);
    };
    const std::int64_t d = ordered(a) - ordered(b);
    return d < 0 ? -d : d;
}

struct Stat {
    std::int64_t max = 0;
    double sum = 0;
    long count = 0;
    void add(std::int64_t u) {
        if (u > max) max = u;
        sum += static_cast<double>(u);
        ++count;
    }
};

template <class T>
void accumulate(int n, const std::vector<RefNode>& refs, Stat (&s)[4]) {
    const auto full = stratum::gauss_legendre<T>(n);
    const auto half = stratum::gauss_legendre_half<T>(n);
    for (int k = 1; k <= (n + 1) / 2; ++k) {
        const RefNode& r = refs[static_cast<std::size_t>(k - 1)];
        const auto i = static_cast<std::size_t>(n - k), j = static_cast<std::size_t>(k - 1);
        s[0].add(ulps(full.nodes[i], static_cast<T>(r.x)));
        s[0].add(ulps(full.nodes[j], static_cast<T>(-r.x)));
        s[1].add(ulps(full.weights[i], static_cast<T>(r.w)));
        s[2].add(ulps(half.nodes[i], static_cast<T>(r.hi)));
        s[2].add(ulps(half.nodes[j], static_cast<T>(r.lo)));
        s[3].add(ulps(half.weights[i], static_cast<T>(r.w / 2)));
    }
}

// Error of the long double results before rounding to double, in ulp of the correctly rounded double.
double fractional_ulps(long double v, quad r) {
    const double rd = static_cast<double>(r);
    if (rd == 0) return static_cast<double>(v) == 0 ? 0 : 1e300;
    const double ulp = std::nextafter(std::fabs(rd), 1e300) - std::fabs(rd);
    return static_cast<double>(qabs(static_cast<quad>(v) - r)) / ulp;
}

void accumulate_unrounded(int n, const std::vector<RefNode>& refs, double (&m)[4]) {
    const auto full = stratum::gauss_legendre<long double>(n);
    const auto half = stratum::gauss_legendre_half<long double>(n);
    for (int k = 1; k <= (n + 1) / 2; ++k) {
        const RefNode& r = refs[static_cast<std::size_t>(k - 1)];
        const auto i = static_cast<std::size_t>(n - k), j = static_cast<std::size_t>(k - 1);
        const double e[4] = {fractional_ulps(full.nodes[i], r.x), fractional_ulps(full.weights[i], r.w),
                             std::max(fractional_ulps(half.nodes[i], r.hi), fractional_ulps(half.nodes[j], r.lo)),
                             fractional_ulps(half.weights[i], r.w / 2)};
        for (int q = 0; q < 4; ++q) m[q] = std::max(m[q], e[q]);
    }
}

void report_range(const char* label, const std::vector<int>& ns) {
    Stat sd[4], sf[4];
    double unrounded[4] = {0, 0, 0, 0};
    for (int n : ns) {
        std::vector<RefNode> refs;
        for (int k = 1; k <= (n + 1) / 2; ++k) refs.push_back(reference_node(n, k));
        accumulate<double>(n, refs, sd);
        accumulate<float>(n, refs, sf);
        accumulate_unrounded(n, refs, unrounded);
    }
    std::printf("%-14s before rounding to double (long double results): max error nodes %.3f ulp, weights %.3f ulp,"
                " half nodes %.3f ulp, half weights %.3f ulp\n",
                label, unrounded[0], unrounded[1], unrounded[2], unrounded[3]);
    const char* names[4] = {"nodes", "weights", "half nodes", "half weights"};
    for (int t = 0; t < 2; ++t) {
        const Stat* s = t == 0 ? sd : sf;
        std::printf("%-14s %-6s", label, t == 0 ? "double" : "float");
        for (int q = 0; q < 4; ++q)
            std::printf("  %s: max = %lld ulp (mean = %.2g ulp)", names[q], static_cast<long long>(s[q].max),
                        s[q].sum / static_cast<double>(s[q].count));
        std::printf("\n");
    }
    std::fflush(stdout);
}

void report(int nmax) {
    const int cross = stratum::detail::gauss_legendre_newton_max_n;
    std::vector<int> a, b;
    for (int n = 1; n <= nmax; ++n) (n <= cross ? a : b).push_back(n);
    char la[64], lb[64];
    std::snprintf(la, sizeof la, "n=1..%d", cross);
    std::snprintf(lb, sizeof lb, "n=%d..%d", cross + 1, nmax);
    report_range(la, a);
    if (!b.empty()) report_range(lb, b);
    for (int n : {2000, 5000, 10000}) {
        char l[32];
        std::snprintf(l, sizeof l, "n=%d", n);
        report_range(l, {n});
    }
}
#endif

}  // namespace

int main(int argc, char** argv) {
    if (argc >= 2 && std::strcmp(argv[1], "write") == 0) {
        write_file();
        return 0;
    }
#ifdef WITH_STRATUM
    if (argc >= 2 && std::strcmp(argv[1], "report") == 0) {
        report(argc >= 3 ? std::atoi(argv[2]) : 1000);
        return 0;
    }
    if (argc >= 4 && std::strcmp(argv[1], "range") == 0) {  // report for n in [argv[2], argv[3]]
        std::vector<int> ns;
        for (int n = std::atoi(argv[2]); n <= std::atoi(argv[3]); ++n) ns.push_back(n);
        report_range("range", ns);
        return 0;
    }
#endif
    std::fprintf(stderr, "usage: %s write | report [nmax] | range n0 n1\n", argv[0]);
    return 2;
}
