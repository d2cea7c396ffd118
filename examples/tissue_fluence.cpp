// tissue_fluence: the fluence rate against depth in a scattering tissue slab lit by a collimated beam, the plot
// tissue optics draws. A slab of single-scattering albedo 0.99, Henyey-Greenstein g = 0.9 (typical of dermis) and
// optical thickness 20 under air through a smooth surface (n = 1.4), over a diffuse floor of albedo 0.4 (bone).
// Prints the fluence rate phi and the net flux at 21 depths for normal incidence, per unit incident flux, and
// the layer's reflectance; the fluence rises above 1 just below the surface (light scattered back up joins the
// beam, and total internal reflection at the surface keeps some of it in) before it decays with depth.
//
// Usage: tissue_fluence [ordinates]   (default 16)
#include <stratum/layer.hpp>

#include <cstdio>
#include <cstdlib>
#include <vector>

int main(int argc, char** argv) {
    stratum::LayerOptions options;
    options.ordinates = argc > 1 ? std::atoi(argv[1]) : 16;
    const double tau = 20;
    stratum::LayerRequest<double> request;
    for (int i = 0; i <= 20; ++i) request.depths.push_back(tau * i / 20);
    const auto layer = stratum::solve_layer(stratum::Slab<double>(0.99, 0.9, tau), stratum::SmoothDielectric<double>(1.0, 1.4),
                                            stratum::Boundary<double>::lambertian(0.4, 1.4), options, request);
    std::printf("reflectance at normal incidence: %.5f (surface %.5f)\n", layer.reflectance(1.0).total(),
                layer.reflectance(1.0).surface);
    std::printf("%10s %14s %14s\n", "depth tau", "fluence rate", "net flux");
    for (const auto& p : layer.depth_profile(1.0)) std::printf("%10.2f %14.6f %14.6f\n", p.depth, p.fluence, p.net_flux);
    return 0;
}
