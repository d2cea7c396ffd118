// plan_material: "simulate only the effects a scene calls for". The planner (stratum/planner.hpp) is told what a
// scene needs from a material and how accurately; it says which model answers, at which settings, with what
// estimated error and at what cost, and solves. Run: build/demo/examples/plan_material
#include <stratum/planner.hpp>

#include <cmath>
#include <cstdio>

namespace {

void show(const char* what, const stratum::PlannedLayer<double>& planned) {
    const stratum::Plan<double>& p = planned.plan;
    if (*what) std::printf("%s\n", what);
    std::printf("  %s\n  planning %.1f ms, final solve %.1f ms\n", p.reason.c_str(), 1e3 * p.planning_seconds,
                1e3 * p.solve_seconds);
}

}  // namespace

int main() {
    using stratum::LayerOutput;
    // Stam's skin layer: air | n = 1.4 | air, Beckmann RMS slope 0.3 on both faces, albedo 0.9, g = 0.8, e^-tau = 0.5.
    const stratum::Material<double> skin{stratum::RoughDielectric<double>(0.3, 1.0, 1.4),
                                         {stratum::Slab<double>::from_transparency(0.9, 0.8, 0.5)}, {},
                                         stratum::RoughDielectric<double>(0.3, 1.4, 1.0)};
    stratum::SceneRequest<double> scene;
    scene.incidence = {0.5};

    scene.outputs = LayerOutput::surface_reflection;  // a specular highlight pass: the top face alone
    show("skin, the top face's reflection:", stratum::solve_planned(skin, scene));

    scene.outputs = LayerOutput::reflectance | LayerOutput::transmittance;  // an energy budget at 60 degrees
    scene.max_ordinates = 128;
    for (const double tolerance : {1e-2, 1e-3, 1e-4}) {
        scene.tolerance = tolerance;
        const auto planned = stratum::solve_planned(skin, scene);
        std::printf("skin, fluxes at mu0 = 0.5 within %.0e: R = %.5f, T = %.5f\n", tolerance,
                    planned.surface.reflectance(0.5).subsurface, planned.surface.transmittance(0.5));
        show("", planned);
    }

    scene.outputs = LayerOutput::surface_reflection | LayerOutput::subsurface_reflection;  // a BRDF for rendering
    scene.tolerance = 1e-2;
    scene.max_ordinates = 64;
    const auto brdf = stratum::solve_planned(skin, scene);
    const stratum::Vec3<double> wi{0.0, std::sqrt(0.75), 0.5}, wo{0.6, 0.0, 0.8};
    std::printf("skin, BRDF within 1e-2 (in flux): f(wi, wo) = %.5f 1/sr\n", brdf.surface.brdf(wi, wo));
    show("", brdf);

    // Milk in a glass: a thick slab under a smooth face, sigma_t = 10 / mm; a renderer at 2 mm per pixel asks whether it
    // needs the diffusion profile at all.
    const stratum::Material<double> milk{stratum::SmoothDielectric<double>(1.0, 1.35),
                                         {stratum::Slab<double>(0.999, 0.7, 1e3)}, {},
                                         stratum::Boundary<double>::index_matched(1.35), 10.0};
    stratum::SceneRequest<double> profile;
    profile.outputs = LayerOutput::reflectance;
    profile.incidence = {1.0};
    profile.tolerance = 1e-3;
    profile.diffusion_profile = true;
    profile.length_scale = 2.0;
    const auto planned = stratum::solve_planned(milk, profile);
    std::printf("milk, diffusion profile: R_d(1 mm) = %.5f / mm^2, diffuse mean free path %.2f mm\n",
                planned.dipole->Rd(1.0), planned.dipole->diffuse_mean_free_path());
    show("", planned);
    return 0;
}
