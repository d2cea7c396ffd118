// tests/reference/reference_phase.hpp -- Henyey-Greenstein Fourier matrices written independently of the library
// (test-only reference for the slab and adding tests; not installed).
#pragma once

#include <cmath>
#include <cstddef>
#include <vector>

namespace stratum_test {

struct Phase {
    std::vector<double> same, opposite;
};

// Henyey-Greenstein Fourier matrices written independently of the library: the Legendre sum
// p_k(x', x) = (2 - delta_k0) sum_{n=k}^{N} (2n+1) g^n Lambda_n^k(x') Lambda_n^k(x) with the normalized
// associated functions Lambda_n^k = sqrt((n-k)!/(n+k)!) P_n^k from their three-term recurrence.
inline std::vector<double> normalized_legendre(int k, int nmax, double x) {
    std::vector<double> out(static_cast<std::size_t>(nmax + 1), 0.0);
    if (k > nmax) return out;
    const double s = std::sqrt(std::fmax(0.0, (1 - x) * (1 + x)));
    double lkk = 1;
    for (int j = 1; j <= k; ++j) lkk *= std::sqrt((2.0 * j - 1) / (2.0 * j)) * s;
    out[static_cast<std::size_t>(k)] = lkk;
    if (k + 1 <= nmax) out[static_cast<std::size_t>(k + 1)] = std::sqrt(2.0 * k + 1) * x * lkk;
    for (int n = k + 2; n <= nmax; ++n) {
        const auto un = static_cast<std::size_t>(n);
        out[un] = ((2.0 * n - 1) * x * out[un - 1] - std::sqrt((n - 1.0) * (n - 1.0) - 1.0 * k * k) * out[un - 2]) /
                  std::sqrt(1.0 * n * n - 1.0 * k * k);
    }
    return out;
}

inline Phase henyey_greenstein(double g, const std::vector<double>& mu, int k, int nmax) {
    const std::size_t m = mu.size();
    Phase p{std::vector<double>(m * m), std::vector<double>(m * m)};
    std::vector<std::vector<double>> lam(m);
    for (std::size_t i = 0; i < m; ++i) lam[i] = normalized_legendre(k, nmax, mu[i]);
    for (std::size_t n = 0; n < m; ++n)
        for (std::size_t j = 0; j < m; ++j) {
            double same = 0, opp = 0;
            for (int l = k; l <= nmax; ++l) {
                const auto ul = static_cast<std::size_t>(l);
                const double term = (2.0 * l + 1) * std::pow(g, l) * lam[j][ul] * lam[n][ul];
                same += term;
                opp += ((l + k) % 2 == 0 ? term : -term);  // P_n^k(-x) = (-1)^{n+k} P_n^k(x)
            }
            const double f = k == 0 ? 1.0 : 2.0;
            p.same[n * m + j] = f * same;
            p.opposite[n * m + j] = f * opp;
        }
    return p;
}

}  // namespace stratum_test
