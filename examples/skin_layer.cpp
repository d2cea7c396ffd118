// skin_layer: Stam's (2001) skin layer -- a scattering slab between two rough dielectric interfaces.
//
// Parameters (Stam, Section 5): n1 = 1 (air), n2 = 1.4 (skin), n3 = 1, Beckmann RMS slope sigma = 0.3 on both
// interfaces, single-scattering albedo 0.9, Henyey-Greenstein g = 0.8, transparency e^{-tau} = 0.5.
// Prints the albedo (surface and subsurface parts) and transmittance for a few incidence angles, the in-plane
// cross-sections of r_s and t_s (the curves of Stam's Figure 4), and writes them as SVG plots
// (skin_layer_rs.svg, skin_layer_ts.svg) in the current directory.
#include <stratum/layer.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>

#include "svg_plot.hpp"

int main() {
    using Real = double;
    const Real pi = 3.14159265358979323846;
    const stratum::RoughDielectric<Real> top(0.3, 1.0, 1.4), bottom(0.3, 1.4, 1.0);
    const auto slab = stratum::Slab<Real>::from_transparency(0.9, 0.8, 0.5);
    stratum::LayerOptions options;
    options.ordinates = 16;  // 32 Fourier modes; see README for the accuracy each choice buys

    const auto start = std::chrono::steady_clock::now();
    const auto layer = stratum::solve_layer(slab, top, bottom, options);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    std::printf("Stam's skin layer: n = 1 | 1.4 | 1, sigma = 0.3, albedo 0.9, g = 0.8, e^-tau = 0.5\n");
    std::printf("solved with %d ordinates and %d Fourier modes in %.0f ms\n\n", layer.ordinates(), layer.modes(), ms);

    std::printf("theta_i   surface   subsurface   albedo   transmittance   absorbed+lost\n");
    for (Real deg : {0.0, 30.0, 60.0, 80.0}) {
        const Real mu = std::cos(deg * pi / 180);
        const auto a = layer.reflectance(mu);
        const Real t = layer.transmittance(mu);
        std::printf("%5.0f     %.4f    %.4f       %.4f   %.4f          %.4f\n", deg, a.surface, a.subsurface,
                    a.total(), t, 1 - a.total() - t);
    }

    // In-plane cross-sections: wi at azimuth pi, wo in the plane of incidence; theta_o < 0 is backward.
    example::Plot rs{"Stam's skin layer: subsurface BRDF r_s in the plane of incidence", "theta_o (deg)",
                     "r_s (1/sr)", {}, false};
    example::Plot ts{"Stam's skin layer: BTDF t_s in the plane of incidence", "theta_o below (deg)", "t_s (1/sr)", {},
                     false};
    stratum::LayeredSurface<Real>::Workspace ws;
    std::printf("\nin-plane r_s and t_s (1/sr); theta_o < 0 on the side of the light\n theta_o");
    const Real incidences[] = {0.0, 30.0, 60.0};
    for (Real deg : incidences) std::printf("   r_s(%2.0f)   t_s(%2.0f)", deg, deg);
    std::printf("\n");
    for (Real deg : incidences) {
        rs.series.push_back({"theta_i = " + std::to_string(static_cast<int>(deg)), {}});
        ts.series.push_back({"theta_i = " + std::to_string(static_cast<int>(deg)), {}});
    }
    for (int j = -88; j <= 88; j += 2) {
        const Real theta_o = j * pi / 180;
        const bool print = j % 16 == 0;
        if (print) std::printf("%7d", j);
        for (std::size_t s = 0; s < 3; ++s) {
            const Real theta_i = incidences[s] * pi / 180;
            const stratum::Vec3<Real> wi{-std::sin(theta_i), 0, std::cos(theta_i)};
            const stratum::Vec3<Real> up{std::sin(theta_o), 0, std::cos(theta_o)};
            const stratum::Vec3<Real> down{std::sin(theta_o), 0, -std::cos(theta_o)};
            const Real r = layer.subsurface_brdf(wi, up, ws), t = layer.btdf(wi, down, ws);
            rs.series[s].points.emplace_back(j, r);
            ts.series[s].points.emplace_back(j, t);
            if (print) std::printf("   %.5f   %.5f", r, t);
        }
        if (print) std::printf("\n");
    }
    const bool ok = rs.write("skin_layer_rs.svg") && ts.write("skin_layer_ts.svg");
    std::printf("\n%s skin_layer_rs.svg and skin_layer_ts.svg\n", ok ? "wrote" : "could not write");
    return ok ? 0 : 1;
}
