// export_skin.cpp -- writes Stam's skin layer as pbrt-v3 .bsdf files and prints the pixel values a pbrt-v3 render
// of a flat square of that material under a uniform white environment (radiance 1) should show.
//
// Build: g++ -std=c++17 -O2 -fopenmp -I../../include export_skin.cpp -o export_skin
// Run:   ./export_skin            (writes skin.bsdf, one-sided, and skin2.bsdf, two-sided)
//
// Conventions (checked against pbrt-v3 src/core/reflection.cpp, FourierBSDF::f): pbrt calls f(wo, wi) with wo
// towards the camera and wi towards the light (TransportMode::Radiance on camera paths), reads the pair
// (mu_i = cos(-wi), mu_o = cos(wo)) and multiplies transmission by eta^2 (eta = 1 here). PbrtBsdfTable::eval(wi, wo)
// takes the same wi (light) and wo (viewer). The pixel radiance of a square lit by L = 1 from every direction is
//   E(wo) = int_{S^2} f(wi, wo) |wi.z| dw_i.
#include <cmath>
#include <cstdio>
#include <functional>
#include <vector>

#include <stratum/stratum.hpp>
#include <stratum/pbrt_bsdf.hpp>
#include <stratum/tabulated_bsdf.hpp>

using V = stratum::Vec3<double>;

// Gauss-Legendre nodes and weights on [-1, 1] (stratum's).
static void gauss_legendre(int n, std::vector<double>& x, std::vector<double>& w) {
    const stratum::Quadrature<double> q = stratum::gauss_legendre<double>(n);
    x = q.nodes;
    w = q.weights;
}

// int over wi of f(wi, wo) |wi.z| dw_i, with the cosine of wi on the panels given by `breaks` (ascending in [-1, 1]),
// `per_panel` Gauss points on each, and n_phi midpoints in [0, pi) (the functions are even in phi).
// Also returns the part from wi above (wi.z > 0: light from above) in *upper.
static double sphere_integral(const std::function<double(V, V)>& f, V wo, const std::vector<double>& breaks,
                              int per_panel, int n_phi, double* upper) {
    std::vector<double> gx, gw;
    gauss_legendre(per_panel, gx, gw);
    std::vector<double> mus, wts;
    for (size_t p = 0; p + 1 < breaks.size(); ++p) {
        const double a = breaks[p], b = breaks[p + 1];
        if (!(b > a)) continue;
        for (int j = 0; j < per_panel; ++j) {
            mus.push_back(0.5 * (a + b) + 0.5 * (b - a) * gx[j]);
            wts.push_back(0.5 * (b - a) * gw[j]);
        }
    }
    double total = 0, up = 0;
#pragma omp parallel for reduction(+ : total, up) schedule(dynamic)
    for (int q = 0; q < static_cast<int>(mus.size()); ++q) {
        const double mu = mus[q], s = std::sqrt(std::fmax(0.0, 1 - mu * mu));
        double sum = 0;
        for (int k = 0; k < n_phi; ++k) {
            const double phi = M_PI * (k + 0.5) / n_phi;
            const V wi{s * std::cos(phi), s * std::sin(phi), mu};
            sum += f(wi, wo);
        }
        const double v = wts[q] * std::fabs(mu) * sum * (2 * M_PI / n_phi);
        total += v;
        if (mu > 0) up += v;
    }
    if (upper) *upper = up;
    return total;
}

int main() {
    stratum::LayerOptions options;
    options.ordinates = 16;
    const auto slab = stratum::Slab<double>::from_transparency(0.9, 0.8, 0.5);
    const stratum::RoughDielectric<double> top(0.3, 1.0, 1.4), bottom(0.3, 1.4, 1.0);
    auto layer = stratum::solve_layer(slab, top, bottom, options);
    // The layer turned over: bottom face first, indices swapped -- for this symmetric layer, the same faces.
    auto flipped = stratum::solve_layer(slab, stratum::RoughDielectric<double>(0.3, 1.0, 1.4),
                                        stratum::RoughDielectric<double>(0.3, 1.4, 1.0), options);
    stratum::TabulatedBSDF<double> table(layer, 3e-3);
    stratum::TabulatedBSDF<double> table2(layer, flipped, 3e-3);
    const stratum::PbrtBsdfTable file = stratum::pbrt_bsdf_table(table);
    const stratum::PbrtBsdfTable file2 = stratum::pbrt_bsdf_table(table2);
    stratum::write_pbrt_bsdf("skin.bsdf", file);
    stratum::write_pbrt_bsdf("skin2.bsdf", file2);
    const stratum::PbrtBsdfTable back = stratum::read_pbrt_bsdf("skin.bsdf");
    std::printf("table: grid %d nodes, error %.3g (tolerance %.1e), two_sided %d; file: nMu %d, mMax %d, coeffs %zu, "
                "eta %g, channels %d; read back: nMu %d\n",
                table.grid_size(), table.error(), table.tolerance(), (int)table.two_sided(), file.size(),
                file.max_order(), file.coeffs.size(), file.eta, file.channels, back.size());
    std::printf("two-sided table: error %.3g; file skin2.bsdf: nMu %d, mMax %d, coeffs %zu\n", table2.error(),
                file2.size(), file2.max_order(), file2.coeffs.size());

    std::vector<double> file_breaks(file.mu.begin(), file.mu.end());  // panels between the file's nodes
    const std::vector<double> hemi_breaks{-1.0, 0.0, 1.0};
    // the cosines 1, 0.866, 0.5, 0.259, and the exact cosines of the rendered angles 30 and 75 degrees
    const double mus_o[] = {1.0, std::cos(0.5 * M_PI / 180), 0.866, std::cos(M_PI / 6), 0.5, 0.259, std::cos(5 * M_PI / 12)};
    std::printf("\nE(mu_o) = int_{S^2} f(wi, wo)|wi.z| dw_i, wo = (sqrt(1-mu_o^2), 0, +-mu_o)\n");
    for (int side = 0; side < 2; ++side) {
        std::printf("\n%s (mu_o %s 0)\n", side == 0 ? "viewer ABOVE the square (wo.z > 0)" : "viewer BELOW (wo.z < 0)",
                    side == 0 ? ">" : "<");
        std::printf("%-8s %-11s %-11s %-11s %-11s %-11s | %-11s %-11s %-11s | %-9s %-9s %-9s\n", "mu_o",
                    "Efile", "Efile.up", "Efile.GL128", "Efile.GL256", "Efile2side", "Etable", "Etable.GL256", "Etable2",
                    "albedoR", "albedoT", "R+T");
        for (double m : mus_o) {
            const double mu_o = side == 0 ? m : -m;
            const V wo{std::sqrt(std::fmax(0.0, 1 - m * m)), 0, mu_o};
            auto ff = [&](V wi, V w) { return file.eval(wi, w); };
            auto ff2 = [&](V wi, V w) { return file2.eval(wi, w); };
            auto ft = [&](V wi, V w) { return table.eval(wi, w); };
            auto ft2 = [&](V wi, V w) { return table2.eval(wi, w); };
            double up = 0, up2 = 0;
            const double e_file = sphere_integral(ff, wo, file_breaks, 8, 1024, &up);
            const double e_file128 = sphere_integral(ff, wo, hemi_breaks, 128, 512, nullptr);
            const double e_file256 = sphere_integral(ff, wo, hemi_breaks, 256, 1024, nullptr);
            const double e_file2 = sphere_integral(ff2, wo, file_breaks, 8, 1024, &up2);
            const double e_tab128 = sphere_integral(ft, wo, hemi_breaks, 128, 512, nullptr);
            const double e_tab256 = sphere_integral(ft, wo, hemi_breaks, 256, 1024, nullptr);
            const double e_tab2 = sphere_integral(ft2, wo, hemi_breaks, 256, 1024, nullptr);
            const auto al = table.albedo(m);
            std::printf("%-8.6f %-11.6f %-11.6f %-11.6f %-11.6f %-11.6f | %-11.6f %-11.6f %-11.6f | %-9.6f %-9.6f %-9.6f\n",
                        mu_o, e_file, up, e_file128, e_file256, e_file2, e_tab128, e_tab256, e_tab2,
                        al.reflectance, al.transmittance, al.reflectance + al.transmittance);
        }
    }
    return 0;
}
