// tissue_fluence: the fluence rate against depth in a scattering tissue slab lit by a collimated beam, the plot
// tissue optics draws. A slab of single-scattering albedo 0.99, Henyey-Greenstein g = 0.9 (typical of dermis) and
// optical thickness 20 under air through a smooth surface (n = 1.4), over a diffuse floor of albedo 0.4 (bone).
// Prints the fluence rate phi and the net flux at 21 depths for normal incidence, per unit incident flux, and
// the layer's reflectance; the fluence rises above 1 just below the surface (light scattered back up joins the
// beam, and total internal reflection at the surface keeps some of it in) before it decays with depth. Then the
// same dermis under an epidermis (n 1.4, albedo 0.9, g 0.8, tau 1) and a glass slide (n 1.5, absorbing, tau 1e-3):
// a stack whose joints refract, its profile through all three slabs (the depth from the top of the glass).
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

    // Glass slide | epidermis | dermis over the floor: 1 | 1.5 | 1.4 | 1.38, the same dermis.
    const std::vector<stratum::Slab<double>> slabs{stratum::Slab<double>(0.0, 0.0, 1e-3), stratum::Slab<double>(0.9, 0.8, 1.0),
                                                   stratum::Slab<double>(0.99, 0.9, tau)};
    const std::vector<stratum::Boundary<double>> joints{stratum::SmoothDielectric<double>(1.5, 1.4),
                                                        stratum::SmoothDielectric<double>(1.4, 1.38)};
    stratum::LayerRequest<double> through;
    for (const double t : {0.0, 1e-3, 0.25, 0.5, 1.0, 1.001, 2.0, 5.0, 10.0, 15.0, 21.001}) through.depths.push_back(t);
    const auto stack = stratum::solve_stack<double>(stratum::SmoothDielectric<double>(1.0, 1.5), slabs, joints,
                                                    stratum::Boundary<double>::lambertian(0.4, 1.38), options, through);
    std::printf("\nglass | epidermis | dermis: reflectance at normal incidence %.5f (the joints' specular part %.5f)\n",
                stack.reflectance(1.0).total(), stack.direct_reflectance(1.0));
    std::printf("%10s %14s %14s\n", "depth tau", "fluence rate", "net flux");
    for (const auto& p : stack.depth_profile(1.0)) std::printf("%10.3f %14.6f %14.6f\n", p.depth, p.fluence, p.net_flux);
    return 0;
}
