// quickstart: the smallest useful stratum program -- Fresnel reflectance and discrete ordinates.
#include <stratum/stratum.hpp>

#include <cstdio>

int main() {
    const double eta = 1.4;  // skin's relative index (Stam 2001)
    std::printf("Fresnel reflectance, air -> eta = %.2f\n", eta);
    for (double mu : {1.0, 0.5, 0.1})
        std::printf("  cos_i = %.2f   F = %.6f\n", mu, stratum::fresnel_dielectric(mu, eta));
    std::printf("internal diffuse reflectance F_dr(%.2f) = %.6f (Egan-Hilgeman fit %.6f)\n", eta,
                stratum::fresnel_diffuse_reflectance(eta), stratum::fresnel_diffuse_reflectance_fit(eta));
    const auto q = stratum::gauss_legendre_half<double>(8);
    std::printf("8 half-range ordinates on [0, 1]:\n");
    for (std::size_t i = 0; i < q.size(); ++i) std::printf("  mu = %.17f  w = %.17f\n", q.nodes[i], q.weights[i]);
    return 0;
}
