// Reference hemispherical energies of a rough dielectric for tests/test_interface_albedo.cpp, from the slow
// facet-slope integral kept in tests/reference/rough_albedo_reference.hpp (the implementation before the fast path) at
// 56 nodes per panel, with its own error estimate |56-node - 40-node| in the last column.
// Build and run from the repository root:
//   g++ -O2 -std=c++17 -Iinclude tests/data/gen_interface_albedo.cpp -o /tmp/gen_albedo
//   /tmp/gen_albedo > tests/data/interface_albedo_reference.txt          (about 15 minutes on one core)
// Columns: sigma, eta = eta_t / eta_i, mu (incidence cosine on the eta_i side), shadowing (0 height-correlated,
// 1 separable, 2 masking only), R, T, reference error estimate.
#include "../reference/rough_albedo_reference.hpp"

#include <cmath>
#include <cstdio>

int main() {
    const double sigmas[] = {1e-4, 0.003, 0.02, 0.1, 0.3, 0.7, 1.0, 1.5, 2.0};
    const double etas[] = {1 / 2.5, 1 / 1.4, 1 / 1.0001, 1 - 1e-9, 1 + 1e-9, 1.0001, 1.1, 1.4, 2.5};
    const double mus[] = {0.0, 1e-4, 0.05, 0.2, 0.5, 0.766, 0.95, 1.0};
    for (double sigma : sigmas)
        for (double eta : etas)
            for (double mu : mus)
                for (int f = 0; f < 3; ++f) {
                    const auto form = static_cast<stratum::Shadowing>(f);
                    const auto a = stratum_test::rough_albedo_reference<double>(sigma, mu, eta, form, 40);
                    const auto b = stratum_test::rough_albedo_reference<double>(sigma, mu, eta, form, 56);
                    std::printf("%.17g %.17g %.17g %d %.17g %.17g %.3e\n", sigma, eta, mu, f, b.reflectance,
                                b.transmittance,
                                std::fmax(std::fabs(a.reflectance - b.reflectance), std::fabs(a.transmittance - b.transmittance)));
                }
}
