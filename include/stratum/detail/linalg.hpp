// stratum/detail/linalg.hpp -- the small dense linear algebra of the layer solver.
//
// Square and rectangular matrices of a few hundred rows at most, stored row-major in a std::vector:
// products, LU with partial pivoting, Cholesky, triangular solves, and the symmetric eigenproblem
// (Householder reduction to tridiagonal form, then implicit QL with Wilkinson-like shifts).
// Dependency-free and templated on the real type (float, double, long double). Not part of the API.
//
// Accuracy: every routine is backward stable; eigenvalues of a symmetric A come out with absolute
// error ~ n eps ||A||, eigenvectors orthonormal to ~ n eps (tests/test_linalg.cpp measures both).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <utility>
#include <vector>

namespace stratum::detail {

/// A dense rows x cols matrix, row-major: element (i, j) is data[i * cols + j].
template <class Real>
struct Matrix {
    std::size_t rows = 0, cols = 0;
    std::vector<Real> data;

    Matrix() = default;
    Matrix(std::size_t r, std::size_t c, Real fill = Real(0)) : rows(r), cols(c), data(r * c, fill) {}

    Real& operator()(std::size_t i, std::size_t j) noexcept { return data[i * cols + j]; }
    const Real& operator()(std::size_t i, std::size_t j) const noexcept { return data[i * cols + j]; }
    Real* row(std::size_t i) noexcept { return data.data() + i * cols; }
    const Real* row(std::size_t i) const noexcept { return data.data() + i * cols; }

    static Matrix identity(std::size_t n) {
        Matrix m(n, n);
        for (std::size_t i = 0; i < n; ++i) m(i, i) = Real(1);
        return m;
    }
};

/// Whether fewer than half of the entries of the first, middle and last rows are nonzero: then the products and
/// solves below skip the zeros (the operators of smooth faces are diagonal, and a mode that does not scatter has
/// R = 0 and a diagonal T). A guess from three rows, O(n): it chooses the faster loop, never the result (counting
/// every entry cost 5% of a layer solve at M = 24).
template <class Real>
bool mostly_zero(const Matrix<Real>& a) noexcept {
    if (a.rows == 0 || a.cols == 0) return false;
    std::size_t nonzero = 0, seen = 0;
    for (const std::size_t i : {std::size_t(0), a.rows / 2, a.rows - 1}) {
        const Real* r = a.row(i);
        for (std::size_t j = 0; j < a.cols; ++j) nonzero += r[j] != Real(0);
        seen += a.cols;
    }
    return 2 * nonzero < seen;
}

/// C = A B. Blocks of 4 rows by 8 columns of C are accumulated in registers over the whole inner dimension (a
/// row of B's block is loaded once per 4 multiply-adds instead of C being loaded and stored per multiply-add: 1.8x
/// the plain i-k-j loop at n = 24, bench/bench_slab.cpp BM_multiply); the edges, and an A that is mostly zero,
/// take the plain loop, which skips A's zeros.
template <class Real>
Matrix<Real> multiply(const Matrix<Real>& a, const Matrix<Real>& b) {
    constexpr std::size_t block_rows = 4, block_cols = 8;
    const std::size_t n = a.rows, inner = a.cols, cols = b.cols;
    Matrix<Real> c(n, cols);
    const std::size_t full_rows = mostly_zero(a) ? 0 : n - n % block_rows, full_cols = cols - cols % block_cols;
    for (std::size_t i = 0; i < full_rows; i += block_rows) {
        for (std::size_t j = 0; j < full_cols; j += block_cols) {
            Real acc[block_rows][block_cols] = {};
            for (std::size_t k = 0; k < inner; ++k) {
                const Real* bk = b.row(k) + j;
                for (std::size_t r = 0; r < block_rows; ++r) {
                    const Real ark = a(i + r, k);
                    for (std::size_t s = 0; s < block_cols; ++s) acc[r][s] += ark * bk[s];
                }
            }
            for (std::size_t r = 0; r < block_rows; ++r)
                for (std::size_t s = 0; s < block_cols; ++s) c(i + r, j + s) = acc[r][s];
        }
        for (std::size_t r = i; r < i + block_rows; ++r)  // the last columns
            for (std::size_t k = 0; k < inner; ++k)
                for (std::size_t j = full_cols; j < cols; ++j) c(r, j) += a(r, k) * b(k, j);
    }
    for (std::size_t i = full_rows; i < n; ++i)  // the last rows (all of them where A is mostly zero)
        for (std::size_t k = 0; k < inner; ++k) {
            const Real aik = a(i, k);
            if (aik == Real(0)) continue;
            const Real* bk = b.row(k);
            Real* ci = c.row(i);
            for (std::size_t j = 0; j < cols; ++j) ci[j] += aik * bk[j];
        }
    return c;
}

/// A^T.
template <class Real>
Matrix<Real> transpose(const Matrix<Real>& a) {
    Matrix<Real> t(a.cols, a.rows);
    for (std::size_t i = 0; i < a.rows; ++i)
        for (std::size_t j = 0; j < a.cols; ++j) t(j, i) = a(i, j);
    return t;
}

/// LU factorization with partial pivoting, P A = L U, stored compactly (unit-lower L below the
/// diagonal, U on and above it); pivot[k] is the row swapped with row k at step k.
/// A zero pivot (exactly singular matrix) is replaced by the smallest normal number times the
/// column scale, so the solve stays finite; `singular` records that it happened.
template <class Real>
struct LU {
    Matrix<Real> factors;
    std::vector<std::size_t> pivot;
    bool singular = false;
};

template <class Real>
LU<Real> lu_factor(Matrix<Real> a) {
    const std::size_t n = a.rows;
    LU<Real> lu;
    lu.pivot.resize(n);
    Real scale = Real(0);
    for (const Real v : a.data) scale = std::max(scale, std::fabs(v));
    const Real tiny = std::numeric_limits<Real>::min() / std::numeric_limits<Real>::epsilon() *
                      std::max(scale, Real(1));
    for (std::size_t k = 0; k < n; ++k) {
        std::size_t p = k;
        Real best = std::fabs(a(k, k));
        for (std::size_t i = k + 1; i < n; ++i)
            if (std::fabs(a(i, k)) > best) best = std::fabs(a(i, k)), p = i;
        lu.pivot[k] = p;
        if (p != k) std::swap_ranges(a.row(k), a.row(k) + n, a.row(p));
        if (!(best > tiny)) {
            lu.singular = true;
            a(k, k) = tiny;
        }
        const Real inv = Real(1) / a(k, k);
        const Real* rk = a.row(k);
        for (std::size_t i = k + 1; i < n; ++i) {
            Real* ri = a.row(i);
            const Real f = ri[k] * inv;
            ri[k] = f;
            if (f == Real(0)) continue;
            for (std::size_t j = k + 1; j < n; ++j) ri[j] -= f * rk[j];
        }
    }
    lu.factors = std::move(a);
    return lu;
}

/// The substitutions of lu_solve on the columns j0 .. j0 + width of B (pivoted already), each row's block accumulated
/// in registers over the rows solved before it (1.6x the row-by-row update at n = 24, BM_lu_solve).
template <std::size_t width, class Real>
void lu_substitute(const Matrix<Real>& f, Matrix<Real>& b, std::size_t j0) noexcept {
    const std::size_t n = f.rows;
    for (std::size_t i = 0; i < n; ++i) {  // forward: unit lower L
        Real acc[width];
        for (std::size_t s = 0; s < width; ++s) acc[s] = b(i, j0 + s);
        const Real* li = f.row(i);
        for (std::size_t k = 0; k < i; ++k) {
            const Real* bk = b.row(k) + j0;
            for (std::size_t s = 0; s < width; ++s) acc[s] -= li[k] * bk[s];
        }
        for (std::size_t s = 0; s < width; ++s) b(i, j0 + s) = acc[s];
    }
    for (std::size_t i = n; i-- > 0;) {  // backward: U
        Real acc[width];
        for (std::size_t s = 0; s < width; ++s) acc[s] = b(i, j0 + s);
        const Real* ui = f.row(i);
        for (std::size_t k = i + 1; k < n; ++k) {
            const Real* bk = b.row(k) + j0;
            for (std::size_t s = 0; s < width; ++s) acc[s] -= ui[k] * bk[s];
        }
        const Real inv = Real(1) / ui[i];
        for (std::size_t s = 0; s < width; ++s) b(i, j0 + s) = acc[s] * inv;
    }
}

/// Solves A X = B in place (B: n x nrhs, row-major) with the factors of A. Factors that are mostly zero (a
/// diagonal system) are applied row by row, skipping their zeros.
template <class Real>
void lu_solve(const LU<Real>& lu, Matrix<Real>& b) {
    constexpr std::size_t width = 8;
    const Matrix<Real>& f = lu.factors;
    const std::size_t n = f.rows, m = b.cols;
    for (std::size_t k = 0; k < n; ++k)
        if (lu.pivot[k] != k) std::swap_ranges(b.row(k), b.row(k) + m, b.row(lu.pivot[k]));
    if (!mostly_zero(f)) {
        std::size_t j = 0;
        for (; j + width <= m; j += width) lu_substitute<width>(f, b, j);
        for (; j < m; ++j) lu_substitute<1>(f, b, j);
        return;
    }
    for (std::size_t i = 1; i < n; ++i) {  // forward: unit lower L
        Real* bi = b.row(i);
        for (std::size_t k = 0; k < i; ++k) {
            const Real lik = f(i, k);
            if (lik == Real(0)) continue;
            const Real* bk = b.row(k);
            for (std::size_t j = 0; j < m; ++j) bi[j] -= lik * bk[j];
        }
    }
    for (std::size_t ii = n; ii-- > 0;) {  // backward: U
        Real* bi = b.row(ii);
        for (std::size_t k = ii + 1; k < n; ++k) {
            const Real uik = f(ii, k);
            if (uik == Real(0)) continue;
            const Real* bk = b.row(k);
            for (std::size_t j = 0; j < m; ++j) bi[j] -= uik * bk[j];
        }
        const Real inv = Real(1) / f(ii, ii);
        for (std::size_t j = 0; j < m; ++j) bi[j] *= inv;
    }
}

/// X = A^{-1} B.
template <class Real>
Matrix<Real> solve(const Matrix<Real>& a, Matrix<Real> b) {
    lu_solve(lu_factor(a), b);
    return b;
}

/// Cholesky factor of a symmetric positive definite A = L L^T (L lower triangular; the upper part
/// of the result is zero). Returns false, leaving `l` unspecified, if a pivot is not positive.
template <class Real>
bool cholesky(const Matrix<Real>& a, Matrix<Real>& l) {
    const std::size_t n = a.rows;
    l = Matrix<Real>(n, n);
    for (std::size_t j = 0; j < n; ++j) {
        Real d = a(j, j);
        const Real* lj = l.row(j);
        for (std::size_t k = 0; k < j; ++k) d -= lj[k] * lj[k];
        if (!(d > Real(0))) return false;
        const Real ljj = std::sqrt(d);
        l(j, j) = ljj;
        for (std::size_t i = j + 1; i < n; ++i) {
            Real s = a(i, j);
            const Real* li = l.row(i);
            for (std::size_t k = 0; k < j; ++k) s -= li[k] * lj[k];
            l(i, j) = s / ljj;
        }
    }
    return true;
}

/// X = L^{-1} B for lower triangular L.
template <class Real>
Matrix<Real> solve_lower(const Matrix<Real>& l, Matrix<Real> b) {
    const std::size_t n = l.rows, m = b.cols;
    for (std::size_t i = 0; i < n; ++i) {
        Real* bi = b.row(i);
        for (std::size_t k = 0; k < i; ++k) {
            const Real lik = l(i, k);
            if (lik == Real(0)) continue;
            const Real* bk = b.row(k);
            for (std::size_t j = 0; j < m; ++j) bi[j] -= lik * bk[j];
        }
        const Real inv = Real(1) / l(i, i);
        for (std::size_t j = 0; j < m; ++j) bi[j] *= inv;
    }
    return b;
}

/// X = L^{-T} B for lower triangular L (a backward substitution with U = L^T).
template <class Real>
Matrix<Real> solve_lower_transposed(const Matrix<Real>& l, Matrix<Real> b) {
    const std::size_t n = l.rows, m = b.cols;
    for (std::size_t ii = n; ii-- > 0;) {
        Real* bi = b.row(ii);
        for (std::size_t k = ii + 1; k < n; ++k) {
            const Real lki = l(k, ii);
            if (lki == Real(0)) continue;
            const Real* bk = b.row(k);
            for (std::size_t j = 0; j < m; ++j) bi[j] -= lki * bk[j];
        }
        const Real inv = Real(1) / l(ii, ii);
        for (std::size_t j = 0; j < m; ++j) bi[j] *= inv;
    }
    return b;
}

/// Eigen-decomposition of a symmetric matrix: A = V diag(values) V^T, V orthogonal; column j of
/// `vectors` belongs to values[j]. Values in ascending order.
template <class Real>
struct SymmetricEigen {
    std::vector<Real> values;
    Matrix<Real> vectors;
    bool converged = true;
};

/// Step 1 of symmetric_eigen: Householder reduction of the symmetric `a` (full storage, overwritten) to
/// tridiagonal form. For k = 0 .. n-3 the reflector H_k = I - beta_k v_k v_k^T, acting on indices k+1 .. n-1,
/// annihilates a(k+2.., k); v_k is kept in row k of `hv`. Returns the diagonal d and the off-diagonal e
/// (e[i] couples i and i + 1, e[n-1] = 0).
template <class Real>
void householder_tridiagonalize(Matrix<Real>& a, std::vector<Real>& d, std::vector<Real>& e, Matrix<Real>& hv,
                                std::vector<Real>& beta) {
    const std::size_t n = a.rows;
    d.assign(n, Real(0));
    e.assign(n, Real(0));
    hv = Matrix<Real>(n, n);
    beta.assign(n, Real(0));
    std::vector<Real> p(n), q(n);
    for (std::size_t k = 0; k + 2 < n; ++k) {
        const std::size_t s = k + 1;  // first index of the trailing block
        Real scale = Real(0);
        for (std::size_t i = s; i < n; ++i) scale = std::max(scale, std::fabs(a(i, k)));
        if (scale == Real(0)) {
            e[k] = Real(0);
            continue;
        }
        Real norm2 = Real(0);
        Real* v = hv.row(k);
        for (std::size_t i = s; i < n; ++i) {
            v[i] = a(i, k) / scale;
            norm2 += v[i] * v[i];
        }
        const Real norm = std::sqrt(norm2);
        const Real xs = v[s];
        const Real alpha = xs > 0 ? -norm : norm;  // H x = alpha e_s, sign chosen against cancellation
        v[s] = xs - alpha;
        const Real vtv = (norm2 - xs * xs) + v[s] * v[s];  // |x - alpha e_s|^2
        if (vtv == Real(0)) {
            e[k] = a(s, k);
            continue;
        }
        const Real b = Real(2) / vtv;
        beta[k] = b;
        e[k] = alpha * scale;
        // Trailing update A <- H A H = A - v w^T - w v^T, p = b A v, w = p - (b/2)(p.v) v.
        Real pv = Real(0);
        for (std::size_t i = s; i < n; ++i) {
            const Real* ai = a.row(i);
            Real sum = Real(0);
            for (std::size_t j = s; j < n; ++j) sum += ai[j] * v[j];
            p[i] = b * sum;
            pv += p[i] * v[i];
        }
        const Real half = b * pv / Real(2);
        for (std::size_t i = s; i < n; ++i) q[i] = p[i] - half * v[i];
        for (std::size_t i = s; i < n; ++i) {
            Real* ai = a.row(i);
            for (std::size_t j = s; j < n; ++j) ai[j] -= v[i] * q[j] + q[i] * v[j];
        }
    }
    for (std::size_t i = 0; i < n; ++i) d[i] = a(i, i);
    if (n >= 2) e[n - 2] = a(n - 1, n - 2);
    e[n - 1] = Real(0);
}

/// Step 2: Z = Q^T with Q = H_0 H_1 ... H_{n-3} (each H symmetric), so row i of Z is column i of Q. In
/// transposed storage Z <- Z H_k changes every row as z_r <- z_r - beta (z_r . v) v.
template <class Real>
Matrix<Real> accumulate_reflectors(const Matrix<Real>& hv, const std::vector<Real>& beta) {
    const std::size_t n = hv.rows;
    Matrix<Real> z = Matrix<Real>::identity(n);
    for (std::size_t kk = n >= 2 ? n - 2 : 0; kk-- > 0;) {
        const Real b = beta[kk];
        if (b == Real(0)) continue;
        const Real* v = hv.row(kk);
        for (std::size_t r = kk + 1; r < n; ++r) {
            Real* zr = z.row(r);
            Real dot = Real(0);
            for (std::size_t j = kk + 1; j < n; ++j) dot += zr[j] * v[j];
            if (dot == Real(0)) continue;
            dot *= b;
            for (std::size_t j = kk + 1; j < n; ++j) zr[j] -= dot * v[j];
        }
    }
    return z;
}

/// sqrt(f^2 + g^2) without std::hypot's cost (6% of a layer solve) where the sum of squares is finite and far above
/// underflow (a square flushed to 0 is then below eps^2 of the sum); std::hypot, which scales, elsewhere.
template <class Real>
Real rotation_radius(Real f, Real g) noexcept {
    constexpr Real eps = std::numeric_limits<Real>::epsilon();
    constexpr Real tiny = std::numeric_limits<Real>::min() / (eps * eps), huge = std::numeric_limits<Real>::max();
    const Real sum = f * f + g * g;
    return sum > tiny && sum <= huge ? std::sqrt(sum) : std::hypot(f, g);
}

/// Step 3: implicit QL with Wilkinson-type shifts on the tridiagonal (d, e), the rotations applied to the rows
/// of z; d ends as the eigenvalues. Returns false if some eigenvalue needed more than 60 iterations.
template <class Real>
bool tridiagonal_ql(std::vector<Real>& d, std::vector<Real>& e, Matrix<Real>& z) {
    const std::size_t n = d.size();
    const Real eps = std::numeric_limits<Real>::epsilon();
    bool converged = true;
    for (std::size_t l = 0; l < n; ++l) {
        int iterations = 0;
        while (true) {
            std::size_t m = l;
            for (; m + 1 < n; ++m) {
                const Real dd = std::fabs(d[m]) + std::fabs(d[m + 1]);
                if (std::fabs(e[m]) <= eps * dd) break;
            }
            if (m == l) break;
            if (++iterations > 60) {
                converged = false;
                break;
            }
            // Shift from the leading 2x2 block, then chase the bulge from m-1 down to l.
            Real g = (d[l + 1] - d[l]) / (Real(2) * e[l]);
            Real r = rotation_radius(g, Real(1));
            g = d[m] - d[l] + e[l] / (g + std::copysign(r, g));
            Real s = Real(1), c = Real(1), pp = Real(0);
            bool underflow = false;
            for (std::size_t i = m; i-- > l;) {
                const Real f = s * e[i], bb = c * e[i];
                r = rotation_radius(f, g);
                e[i + 1] = r;
                if (r == Real(0)) {  // recover from underflow: split here
                    d[i + 1] -= pp;
                    e[m] = Real(0);
                    underflow = true;
                    break;
                }
                s = f / r;
                c = g / r;
                g = d[i + 1] - pp;
                r = (d[i] - g) * s + Real(2) * c * bb;
                pp = s * r;
                d[i + 1] = g + pp;
                g = c * r - bb;
                Real* zi = z.row(i);
                Real* zi1 = z.row(i + 1);
                for (std::size_t k = 0; k < n; ++k) {
                    const Real t = zi1[k];
                    zi1[k] = s * zi[k] + c * t;
                    zi[k] = c * zi[k] - s * t;
                }
            }
            if (underflow) continue;
            d[l] -= pp;
            e[l] = g;
            e[m] = Real(0);
        }
    }
    return converged;
}

/// Eigen-decomposition of a symmetric matrix by Householder tridiagonalization and the implicit QL
/// algorithm (the classical tred2/tql2 pair, written afresh): ~ (4/3 + 4/3 + ~6) n^3 flops with vectors.
/// Only the lower triangle of `a_in` is read. The accumulated transformation is kept transposed (rows =
/// eigenvectors) so that every plane rotation and reflection works on contiguous rows.
template <class Real>
SymmetricEigen<Real> symmetric_eigen(const Matrix<Real>& a_in) {
    const std::size_t n = a_in.rows;
    SymmetricEigen<Real> out;
    out.values.assign(n, Real(0));
    if (n == 0) return out;
    Matrix<Real> a(n, n);  // full symmetric copy from the lower triangle
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = 0; j <= i; ++j) a(i, j) = a(j, i) = a_in(i, j);
    std::vector<Real> d, e, beta;
    Matrix<Real> hv;
    householder_tridiagonalize(a, d, e, hv, beta);
    Matrix<Real> z = accumulate_reflectors(hv, beta);
    out.converged = tridiagonal_ql(d, e, z);
    // Step 4: ascending order, vectors as columns.
    std::vector<std::size_t> order(n);
    for (std::size_t i = 0; i < n; ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) { return d[x] < d[y]; });
    out.vectors = Matrix<Real>(n, n);
    for (std::size_t j = 0; j < n; ++j) {
        out.values[j] = d[order[j]];
        const Real* zr = z.row(order[j]);
        for (std::size_t i = 0; i < n; ++i) out.vectors(i, j) = zr[i];
    }
    return out;
}

}  // namespace stratum::detail
