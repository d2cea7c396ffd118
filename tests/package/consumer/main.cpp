// Includes the umbrella header and evaluates something from it: the package is usable as installed.
#include <stratum/stratum.hpp>

#include <cstdio>

int main() {
    const double f = stratum::fresnel_dielectric(1.0, 1.5);  // normal incidence: 0.04
    std::printf("F(1, 1.5) = %.6f\n", f);
    return (f > 0.0399 && f < 0.0401) ? 0 : 1;
}
