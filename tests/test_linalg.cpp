// Dense linear algebra of the layer solver: LU, Cholesky, triangular solves, symmetric eigen-solver.
// References: residuals and orthogonality (backward-error bounds ~ n eps ||A||), matrices with known
// spectra built as Q diag(lambda) Q^T, closed forms (2 x 2, diagonal, the second-difference matrix).
#include <doctest/doctest.h>

#include <stratum/detail/linalg.hpp>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

using stratum::detail::Matrix;

namespace {

// Uniform in [-1, 1) from the raw 64-bit stream (std distributions differ across libraries).
struct Random {
    std::mt19937_64 engine;
    explicit Random(std::uint64_t seed) : engine(seed) {}
    double operator()() { return static_cast<double>(engine() >> 11) * 0x1.0p-52 - 1.0; }
};

template <class Real>
Matrix<Real> random_symmetric(std::size_t n, Random& rng) {
    Matrix<Real> a(n, n);
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = 0; j <= i; ++j) a(i, j) = a(j, i) = static_cast<Real>(rng());
    return a;
}

template <class Real>
Real max_abs(const Matrix<Real>& a) {
    Real m = 0;
    for (Real v : a.data) m = std::fmax(m, std::fabs(v));
    return m;
}

// Random orthogonal matrix: product of n random Householder reflections.
Matrix<double> random_orthogonal(std::size_t n, Random& rng) {
    Matrix<double> q = Matrix<double>::identity(n);
    for (std::size_t r = 0; r < n; ++r) {
        std::vector<double> v(n);
        double norm2 = 0;
        for (double& x : v) x = rng(), norm2 += x * x;
        for (std::size_t i = 0; i < n; ++i) {
            double dot = 0;
            for (std::size_t j = 0; j < n; ++j) dot += q(i, j) * v[j];
            for (std::size_t j = 0; j < n; ++j) q(i, j) -= 2 * dot * v[j] / norm2;
        }
    }
    return q;
}

// max |A V - V diag(values)| / ||A||_max and max |V^T V - I|.
template <class Real>
void eigen_errors(const Matrix<Real>& a, const stratum::detail::SymmetricEigen<Real>& e, Real& residual, Real& orth) {
    const std::size_t n = a.rows;
    Matrix<Real> av = stratum::detail::multiply(a, e.vectors);
    residual = 0;
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = 0; j < n; ++j)
            residual = std::fmax(residual, std::fabs(av(i, j) - e.vectors(i, j) * e.values[j]));
    residual /= std::fmax(max_abs(a), std::numeric_limits<Real>::min());
    Matrix<Real> vtv = stratum::detail::multiply(stratum::detail::transpose(e.vectors), e.vectors);
    orth = 0;
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = 0; j < n; ++j) orth = std::fmax(orth, std::fabs(vtv(i, j) - (i == j ? 1 : 0)));
}

}  // namespace

TEST_CASE("symmetric eigen-solver: residual and orthogonality at the backward-error level, n = 1..128") {
    Random rng(20260422);
    const double eps = std::numeric_limits<double>::epsilon();
    for (std::size_t n : {1u, 2u, 3u, 5u, 8u, 16u, 33u, 64u, 128u}) {
        for (int trial = 0; trial < 3; ++trial) {
            const Matrix<double> a = random_symmetric<double>(n, rng);
            const auto e = stratum::detail::symmetric_eigen(a);
            REQUIRE(e.converged);
            double res, orth;
            eigen_errors(a, e, res, orth);
            // Householder + QL is backward stable: errors ~ c n eps with a modest c; 4 n eps is generous
            // enough for rounding accumulation and still fails for any algorithmic slip (errors O(1)).
            CHECK(res <= 4.0 * static_cast<double>(n) * eps);
            CHECK(orth <= 4.0 * static_cast<double>(n) * eps);
            for (std::size_t j = 1; j < n; ++j) CHECK(e.values[j - 1] <= e.values[j]);
            double trace = 0, sum = 0;
            for (std::size_t i = 0; i < n; ++i) trace += a(i, i), sum += e.values[i];
            CHECK(std::fabs(trace - sum) <= 4.0 * static_cast<double>(n) * eps * static_cast<double>(n));
        }
    }
}

TEST_CASE("symmetric eigen-solver recovers a prescribed spectrum, including clusters and a zero") {
    Random rng(7);
    const std::size_t n = 40;
    const Matrix<double> q = random_orthogonal(n, rng);
    std::vector<double> lambda(n);
    for (std::size_t i = 0; i < n; ++i) lambda[i] = std::pow(10.0, -8.0 + 10.0 * static_cast<double>(i) / (n - 1));
    lambda[0] = 0;             // exact zero
    lambda[5] = lambda[6] = lambda[7] = 0.5;  // a triple eigenvalue
    Matrix<double> a(n, n);
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = 0; j < n; ++j) {
            double s = 0;
            for (std::size_t k = 0; k < n; ++k) s += q(i, k) * lambda[k] * q(j, k);
            a(i, j) = s;
        }
    for (std::size_t j = 0; j < n; ++j)
        for (std::size_t i = 0; i < j; ++i) a(i, j) = a(j, i);  // exactly symmetric
    const auto e = stratum::detail::symmetric_eigen(a);
    std::vector<double> sorted = lambda;
    std::sort(sorted.begin(), sorted.end());
    // Absolute eigenvalue error is bounded by ~ n eps ||A|| (Weyl); ||A|| = 100 here, plus the rounding
    // of forming A itself (~ n eps ||A||).
    const double bound = 8.0 * n * std::numeric_limits<double>::epsilon() * 100.0;
    for (std::size_t i = 0; i < n; ++i) CHECK(std::fabs(e.values[i] - sorted[i]) <= bound);
    double res, orth;
    eigen_errors(a, e, res, orth);
    CHECK(orth <= 4.0 * n * std::numeric_limits<double>::epsilon());
}

TEST_CASE("symmetric eigen-solver: closed forms (diagonal, identity, zero, 2x2, second-difference matrix)") {
    {   // diagonal: exact, sorted
        Matrix<double> a(4, 4);
        a(0, 0) = 3, a(1, 1) = -1, a(2, 2) = 2, a(3, 3) = 0;
        const auto e = stratum::detail::symmetric_eigen(a);
        CHECK(e.values == std::vector<double>{-1, 0, 2, 3});
    }
    {   // identity and zero: every vector is an eigenvector; V must still be orthogonal
        for (double s : {0.0, 1.0}) {
            Matrix<double> a = Matrix<double>::identity(6);
            for (double& x : a.data) x *= s;
            const auto e = stratum::detail::symmetric_eigen(a);
            double res, orth;
            eigen_errors(a, e, res, orth);
            for (double v : e.values) CHECK(v == s);
            CHECK(orth <= 1e-15);
        }
    }
    {   // [[a, b], [b, c]]: (a + c)/2 +- sqrt(((a - c)/2)^2 + b^2)
        Matrix<double> a(2, 2);
        a(0, 0) = 2, a(0, 1) = a(1, 0) = 1e-3, a(1, 1) = 2 + 1e-9;
        const auto e = stratum::detail::symmetric_eigen(a);
        const double mid = 2 + 0.5e-9, rad = std::hypot(0.5e-9, 1e-3);
        CHECK(std::fabs(e.values[0] - (mid - rad)) <= 4e-16 * 2);
        CHECK(std::fabs(e.values[1] - (mid + rad)) <= 4e-16 * 2);
    }
    {   // tridiag(-1, 2, -1) of order n: eigenvalues 2 - 2 cos(j pi / (n + 1))
        const std::size_t n = 50;
        Matrix<double> a(n, n);
        for (std::size_t i = 0; i < n; ++i) {
            a(i, i) = 2;
            if (i + 1 < n) a(i, i + 1) = a(i + 1, i) = -1;
        }
        const auto e = stratum::detail::symmetric_eigen(a);
        const double pi = 3.14159265358979323846;
        for (std::size_t j = 0; j < n; ++j) {
            const double exact = 2 - 2 * std::cos(static_cast<double>(j + 1) * pi / (n + 1));
            CHECK(std::fabs(e.values[j] - exact) <= 8 * n * std::numeric_limits<double>::epsilon());
        }
    }
}

TEST_CASE("symmetric eigen-solver compiles and is accurate in float and long double") {
    Random rng(99);
    for (std::size_t n : {7u, 24u}) {
        const Matrix<float> af = random_symmetric<float>(n, rng);
        const auto ef = stratum::detail::symmetric_eigen(af);
        float resf, orthf;
        eigen_errors(af, ef, resf, orthf);
        CHECK(resf <= 4.0f * static_cast<float>(n) * std::numeric_limits<float>::epsilon());
        CHECK(orthf <= 4.0f * static_cast<float>(n) * std::numeric_limits<float>::epsilon());
        const Matrix<long double> al = random_symmetric<long double>(n, rng);
        const auto el = stratum::detail::symmetric_eigen(al);
        long double resl, orthl;
        eigen_errors(al, el, resl, orthl);
        CHECK(resl <= 4.0L * static_cast<long double>(n) * std::numeric_limits<long double>::epsilon());
        CHECK(orthl <= 4.0L * static_cast<long double>(n) * std::numeric_limits<long double>::epsilon());
    }
}

TEST_CASE("LU with partial pivoting solves to the backward-error level and needs pivoting") {
    Random rng(11);
    for (std::size_t n : {1u, 2u, 10u, 64u, 200u}) {
        Matrix<double> a(n, n), x(n, 3);
        for (double& v : a.data) v = rng();
        for (double& v : x.data) v = rng();
        Matrix<double> b = stratum::detail::multiply(a, x);
        const Matrix<double> sol = stratum::detail::solve(a, b);
        // Residual |A sol - b| <= c n eps |A| |sol| for GEPP on random matrices (growth is small).
        const Matrix<double> r = stratum::detail::multiply(a, sol);
        double worst = 0;
        for (std::size_t i = 0; i < b.data.size(); ++i) worst = std::fmax(worst, std::fabs(r.data[i] - b.data[i]));
        const double dn = static_cast<double>(n);
        CHECK(worst <= 16.0 * dn * dn * std::numeric_limits<double>::epsilon() * max_abs(a) * max_abs(sol));
    }
    // A zero leading entry: fails without row exchanges.
    Matrix<double> a(2, 2);
    a(0, 0) = 0, a(0, 1) = 1, a(1, 0) = 1, a(1, 1) = 1;
    Matrix<double> b(2, 1);
    b(0, 0) = 2, b(1, 0) = 3;
    const Matrix<double> x = stratum::detail::solve(a, b);
    CHECK(x(0, 0) == 1.0);
    CHECK(x(1, 0) == 2.0);
}

TEST_CASE("blocked products and many-column solves agree with plain loops on shapes off the blocks") {
    // multiply accumulates 4 x 8 blocks and lu_solve 8 columns at a time, with plain loops at the edges: every
    // shape below mixes both. Reference: the same sums in long double; bound: inner * eps * sum |a| |b| per entry.
    // A that is mostly zero takes the plain loop that skips zeros: both paths are covered (sparse: 3 in 4 zero).
    Random rng(29);
    const std::size_t sizes[] = {1, 3, 4, 5, 8, 9, 13, 24, 33};
    for (bool sparse : {false, true})
    for (std::size_t rows : sizes)
        for (std::size_t inner : sizes)
            for (std::size_t cols : sizes) {
                Matrix<double> a(rows, inner), b(inner, cols);
                for (double& v : a.data) v = rng();
                if (sparse)
                    for (double& v : a.data) v = std::fabs(v) < 0.75 ? 0.0 : v;
                for (double& v : b.data) v = rng();
                const Matrix<double> c = stratum::detail::multiply(a, b);
                REQUIRE(c.rows == rows);
                REQUIRE(c.cols == cols);
                double worst = 0;
                for (std::size_t i = 0; i < rows; ++i)
                    for (std::size_t j = 0; j < cols; ++j) {
                        long double exact = 0, scale = 0;
                        for (std::size_t k = 0; k < inner; ++k) {
                            exact += static_cast<long double>(a(i, k)) * b(k, j);
                            scale += std::fabs(static_cast<long double>(a(i, k)) * b(k, j));
                        }
                        if (scale > 0) worst = std::fmax(worst, static_cast<double>(std::fabs(c(i, j) - exact) / scale));
                        else worst = std::fmax(worst, std::fabs(c(i, j)));
                    }
                CHECK(worst <= static_cast<double>(inner) * std::numeric_limits<double>::epsilon());
            }
    for (bool sparse : {false, true})  // sparse: a diagonal matrix plus a few entries (mostly-zero factors)
    for (std::size_t n : {1u, 7u, 24u, 41u})
        for (std::size_t cols : {1u, 8u, 19u}) {
            Matrix<double> a(n, n), x(n, cols);
            for (double& v : a.data) v = sparse ? (std::fabs(rng()) < 0.9 ? 0.0 : rng()) : rng();
            if (sparse)
                for (std::size_t i = 0; i < n; ++i) a(i, i) = 2 + rng();
            for (double& v : x.data) v = rng();
            const Matrix<double> b = stratum::detail::multiply(a, x);
            const Matrix<double> r = stratum::detail::multiply(a, stratum::detail::solve(a, b));
            double worst = 0;
            for (std::size_t i = 0; i < b.data.size(); ++i) worst = std::fmax(worst, std::fabs(r.data[i] - b.data[i]));
            const double dn = static_cast<double>(n);
            // (measured: at most 0.69 n^2 eps |A| |X|)
            CHECK(worst <= 16.0 * dn * dn * std::numeric_limits<double>::epsilon() * max_abs(a) * max_abs(x));
        }
}

TEST_CASE("the plane rotations' radius is hypot to an ulp, also where the squares overflow or underflow") {
    Random rng(31);
    for (int i = 0; i < 1000; ++i) {
        const double f = rng() * std::pow(10.0, 300 * rng()), g = rng() * std::pow(10.0, 300 * rng());
        const double r = stratum::detail::rotation_radius(f, g), h = std::hypot(f, g);
        CHECK(std::isfinite(r));
        CHECK(std::fabs(r - h) <= std::nextafter(h, HUGE_VAL) - h);  // (1 ulp measured over 1e5 pairs)
    }
    CHECK(stratum::detail::rotation_radius(0.0, 0.0) == 0.0);
    CHECK(stratum::detail::rotation_radius(1e200, 1e200) == std::hypot(1e200, 1e200));
    CHECK(stratum::detail::rotation_radius(3e-200, 4e-200) == std::hypot(3e-200, 4e-200));
    CHECK(stratum::detail::rotation_radius(3.0f, 4.0f) == 5.0f);
}

TEST_CASE("LU of an exactly singular matrix reports it and stays finite") {
    Matrix<double> a(3, 3);
    for (std::size_t i = 0; i < 3; ++i)
        for (std::size_t j = 0; j < 3; ++j) a(i, j) = static_cast<double>(i + 1);  // rank 1
    const auto lu = stratum::detail::lu_factor(a);
    CHECK(lu.singular);
    Matrix<double> b(3, 1, 0.0);
    stratum::detail::lu_solve(lu, b);
    for (double v : b.data) CHECK(std::isfinite(v));
}

TEST_CASE("Cholesky reproduces A = L L^T and refuses a matrix that is not positive definite") {
    Random rng(5);
    const std::size_t n = 30;
    Matrix<double> g(n, n);
    for (double& v : g.data) v = rng();
    Matrix<double> a = stratum::detail::multiply(g, stratum::detail::transpose(g));
    for (std::size_t i = 0; i < n; ++i) a(i, i) += 1;
    Matrix<double> l;
    REQUIRE(stratum::detail::cholesky(a, l));
    const Matrix<double> llt = stratum::detail::multiply(l, stratum::detail::transpose(l));
    double worst = 0;
    for (std::size_t i = 0; i < a.data.size(); ++i) worst = std::fmax(worst, std::fabs(llt.data[i] - a.data[i]));
    CHECK(worst <= 4.0 * static_cast<double>(n) * std::numeric_limits<double>::epsilon() * max_abs(a));
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = i + 1; j < n; ++j) CHECK(l(i, j) == 0.0);
    // Triangular solves invert L and L^T.
    Matrix<double> b(n, 2);
    for (double& v : b.data) v = rng();
    const Matrix<double> y = stratum::detail::solve_lower(l, b);
    const Matrix<double> ly = stratum::detail::multiply(l, y);
    const Matrix<double> z = stratum::detail::solve_lower_transposed(l, b);
    const Matrix<double> ltz = stratum::detail::multiply(stratum::detail::transpose(l), z);
    for (std::size_t i = 0; i < b.data.size(); ++i) {
        CHECK(std::fabs(ly.data[i] - b.data[i]) <= 1e-12);
        CHECK(std::fabs(ltz.data[i] - b.data[i]) <= 1e-12);
    }
    Matrix<double> indefinite = Matrix<double>::identity(3);
    indefinite(2, 2) = -1e-300;
    CHECK_FALSE(stratum::detail::cholesky(indefinite, l));
}
