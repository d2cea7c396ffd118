// stratum/quadrature.hpp -- Gauss-Legendre rules on [-1, 1] and half-range rules on [0, 1].
//
// PROVISIONAL implementation (Newton on the three-term recurrence in long double); the accurate
// O(n) version replaces it. The API below is fixed.
#pragma once

#include <cmath>
#include <cstddef>
#include <vector>

#include "detail/validate.hpp"

namespace stratum {

/// A quadrature rule: integral f ~ sum_i weights[i] f(nodes[i]); nodes ascending.
template <class Real = double>
struct Quadrature {
    std::vector<Real> nodes;
    std::vector<Real> weights;
    std::size_t size() const noexcept { return nodes.size(); }
};

/// n-point Gauss-Legendre rule on [-1, 1]: exact for polynomials of degree <= 2n - 1; weights sum to 2.
/// Throws std::invalid_argument for n < 1.
template <class Real = double>
Quadrature<Real> gauss_legendre(int n) {
    detail::require_count("n", n, 1);
    using W = long double;
    const W pi = 3.141592653589793238462643383279502884L;
    Quadrature<Real> q;
    q.nodes.resize(static_cast<std::size_t>(n));
    q.weights.resize(static_cast<std::size_t>(n));
    for (int i = 0; i < (n + 1) / 2; ++i) {
        W x = std::cos(pi * (static_cast<W>(i) + 0.75L) / (static_cast<W>(n) + 0.5L));
        W dp = 0;
        for (int iter = 0; iter < 100; ++iter) {
            W p0 = 1, p1 = x;
            for (int l = 2; l <= n; ++l) {
                const W p2 = ((2 * l - 1) * x * p1 - (l - 1) * p0) / l;
                p0 = p1;
                p1 = p2;
            }
            if (n == 1) p0 = 1, p1 = x;
            dp = n * (x * p1 - p0) / (x * x - 1);
            const W dx = p1 / dp;
            x -= dx;
            if (std::fabs(dx) < 1e-19L) break;
        }
        const W w = 2 / ((1 - x * x) * dp * dp);
        const auto lo = static_cast<std::size_t>(i), hi = static_cast<std::size_t>(n - 1 - i);
        q.nodes[lo] = static_cast<Real>(-x);
        q.nodes[hi] = static_cast<Real>(x);
        q.weights[lo] = q.weights[hi] = static_cast<Real>(w);
    }
    if (n % 2 == 1) q.nodes[static_cast<std::size_t>(n / 2)] = Real(0);
    return q;
}

/// n-point half-range ("double Gauss") rule on [0, 1]: the Gauss-Legendre rule mapped to [0, 1];
/// weights sum to 1. The ordinates of the discrete-ordinate method (one hemisphere).
template <class Real = double>
Quadrature<Real> gauss_legendre_half(int n) {
    const Quadrature<long double> full = gauss_legendre<long double>(n);
    Quadrature<Real> q;
    for (std::size_t i = 0; i < full.size(); ++i) {
        q.nodes.push_back(static_cast<Real>((1 + full.nodes[i]) / 2));
        q.weights.push_back(static_cast<Real>(full.weights[i] / 2));
    }
    return q;
}

}  // namespace stratum
