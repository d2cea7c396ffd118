// expect_file.cpp -- E(wo) = int_{S^2} f(wi, wo) |wi.z| dw_i of any pbrt-v3 .bsdf file, as stratum's re-implementation
// of pbrt-v3's FourierBSDF::f evaluates it (PbrtBsdfTable::eval), for a viewer above and below at the given angles
// (degrees from the normal). Gauss-Legendre on each interval between the file's cosines (`per_panel` points),
// n_phi midpoints in azimuth; run twice with doubled resolution to check convergence.
// Build: g++ -std=c++17 -O2 -fopenmp -I../../include expect_file.cpp -o expect_file
// Usage: ./expect_file file.bsdf per_panel n_phi angle...
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>
#include <stratum/pbrt_bsdf.hpp>
using V = stratum::Vec3<double>;
// Gauss-Legendre nodes and weights on [-1, 1] (stratum's).
static void gauss_legendre(int n, std::vector<double>& x, std::vector<double>& w) {
    const stratum::Quadrature<double> q = stratum::gauss_legendre<double>(n);
    x = q.nodes;
    w = q.weights;
}
int main(int argc, char** argv) {
    if (argc < 5) { std::fprintf(stderr, "usage: %s file.bsdf per_panel n_phi angle...\n", argv[0]); return 1; }
    const stratum::PbrtBsdfTable t = stratum::read_pbrt_bsdf(argv[1]);
    const int per_panel = std::atoi(argv[2]), n_phi = std::atoi(argv[3]);
    std::printf("# %s: nMu %d, mMax %d, channels %d, eta %g; %d points per panel, %d in phi\n", argv[1], t.size(),
                t.max_order(), t.channels, t.eta, per_panel, n_phi);
    std::printf("# viewer theta_deg mu_o E_Y E_R E_G E_B\n");
    std::vector<double> gx, gw, mus, wts;
    gauss_legendre(per_panel, gx, gw);
    for (int p = 0; p + 1 < t.size(); ++p) {
        const double a = t.mu[p], b = t.mu[p + 1];
        if (!(b > a)) continue;
        for (int j = 0; j < per_panel; ++j) { mus.push_back(0.5 * (a + b) + 0.5 * (b - a) * gx[j]); wts.push_back(0.5 * (b - a) * gw[j]); }
    }
    for (int side = 0; side < 2; ++side)
        for (int k = 4; k < argc; ++k) {
            const double th = std::atof(argv[k]) * M_PI / 180, mu_o = (side ? -1 : 1) * std::cos(th);
            const V wo{std::sin(th), 0, mu_o};
            double e[4] = {0, 0, 0, 0};
            double ey = 0, er = 0, eg = 0, eb = 0;
#pragma omp parallel for reduction(+ : ey, er, eg, eb) schedule(dynamic)
            for (int q = 0; q < (int)mus.size(); ++q) {
                const double mu = mus[q], s = std::sqrt(std::fmax(0.0, 1 - mu * mu));
                double sy = 0, sr = 0, sg = 0, sb = 0, rgb[3];
                for (int j = 0; j < n_phi; ++j) {
                    const double phi = M_PI * (j + 0.5) / n_phi;
                    sy += t.eval(V{s * std::cos(phi), s * std::sin(phi), mu}, wo, rgb);
                    sr += rgb[0]; sg += rgb[1]; sb += rgb[2];
                }
                const double w = wts[q] * std::fabs(mu) * 2 * M_PI / n_phi;
                ey += w * sy; er += w * sr; eg += w * sg; eb += w * sb;
            }
            e[0] = ey; e[1] = er; e[2] = eg; e[3] = eb;
            std::printf("%s %g %.8f %.8f %.8f %.8f %.8f\n", side ? "below" : "above", std::atof(argv[k]), mu_o, e[0], e[1], e[2], e[3]);
        }
    return 0;
}
