// dipole_profile: the dipole for Jensen et al.'s measured skin, marble and milk.
//
// Prints per channel (R, G, B) the total diffuse reflectance R_d, the reduced albedo alpha' and the diffuse
// mean free path; recovers alpha' from R_d (what a shader does with an artist's colour); writes the radial
// profiles R_d(r) as an SVG plot, dipole_profiles.svg, into the current directory; and prints the
// R_d -> alpha' table a shader would embed (eta = 1.3).
//
// Usage: dipole_profile [table_entries]   (default 65)
#include <stratum/dipole.hpp>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

namespace {

struct Material {
    const char* name;
    std::array<float, 3> sigma_s_prime;  // 1/mm
    std::array<float, 3> sigma_a;        // 1/mm
};

// Jensen, Marschner, Levoy, Hanrahan, "A Practical Model for Subsurface Light Transport", SIGGRAPH 2001,
// Figure 5 (table of measured sigma_s' and sigma_a in mm^-1, R, G, B), used with eta = 1.3.
const Material materials[] = {
    {"skin1", {0.74f, 0.88f, 1.01f}, {0.032f, 0.17f, 0.48f}},
    {"skin2", {1.09f, 1.59f, 1.79f}, {0.013f, 0.070f, 0.145f}},
    {"marble", {2.19f, 2.62f, 3.00f}, {0.0021f, 0.0041f, 0.0071f}},
    {"wholemilk", {2.55f, 3.21f, 3.77f}, {0.0011f, 0.0024f, 0.014f}},
};

constexpr float eta = 1.3f;
const char* channel_colour[3] = {"#d62728", "#2ca02c", "#1f77b4"};

void write_svg(const std::string& path) {
    const double width = 720, height = 460, left = 70, right = 20, top = 30, bottom = 50;
    const double r_max = 8;                  // mm
    const double log_lo = -6, log_hi = 1;    // log10 of R_d(r) in 1/mm^2
    auto px = [&](double r) { return left + (width - left - right) * r / r_max; };
    auto py = [&](double v) {
        const double l = std::log10(std::fmax(v, 1e-30));
        return top + (height - top - bottom) * (log_hi - std::fmin(std::fmax(l, log_lo), log_hi)) / (log_hi - log_lo);
    };
    std::ofstream svg(path);
    svg << "<svg xmlns='http://www.w3.org/2000/svg' width='" << width << "' height='" << height
        << "' font-family='sans-serif' font-size='12'>\n<rect width='100%' height='100%' fill='white'/>\n";
    svg << "<text x='" << width / 2 << "' y='18' text-anchor='middle'>Dipole radial profile R_d(r), eta = 1.3 "
           "(solid: skin1, dashed: marble; Jensen et al. 2001)</text>\n";
    for (int e = static_cast<int>(log_lo); e <= static_cast<int>(log_hi); ++e) {
        const double y = py(std::pow(10.0, e));
        svg << "<line x1='" << left << "' x2='" << width - right << "' y1='" << y << "' y2='" << y
            << "' stroke='#ddd'/><text x='" << left - 6 << "' y='" << y + 4 << "' text-anchor='end'>1e" << e
            << "</text>\n";
    }
    for (int r = 0; r <= static_cast<int>(r_max); ++r) {
        const double x = px(r);
        svg << "<line x1='" << x << "' x2='" << x << "' y1='" << top << "' y2='" << height - bottom
            << "' stroke='#eee'/><text x='" << x << "' y='" << height - bottom + 16 << "' text-anchor='middle'>" << r
            << "</text>\n";
    }
    svg << "<text x='" << width / 2 << "' y='" << height - 10 << "' text-anchor='middle'>r (mm)</text>\n";
    svg << "<text x='16' y='" << height / 2 << "' transform='rotate(-90 16 " << height / 2
        << ")' text-anchor='middle'>R_d(r) (1/mm^2)</text>\n";
    for (const Material* m : {&materials[0], &materials[2]}) {
        const auto dipoles = stratum::make_dipoles<float, 3>(m->sigma_a, m->sigma_s_prime, eta);
        for (std::size_t c = 0; c < 3; ++c) {
            svg << "<polyline fill='none' stroke='" << channel_colour[c] << "' stroke-width='1.6'"
                << (m == &materials[2] ? " stroke-dasharray='6 4'" : "") << " points='";
            for (int i = 0; i <= 400; ++i) {
                const float r = static_cast<float>(r_max * i / 400);
                svg << px(r) << ',' << py(dipoles[c].Rd(r)) << ' ';
            }
            svg << "'/>\n";
        }
    }
    svg << "</svg>\n";
}

}  // namespace

int main(int argc, char** argv) {
    const int entries = argc > 1 ? std::atoi(argv[1]) : 65;
    if (entries < 2) {
        std::fprintf(stderr, "table_entries must be >= 2\n");
        return 1;
    }

    // One boundary shared by every channel and material (A from the Jensen F_dr fit, the default).
    const auto boundary = stratum::DipoleBoundary<float>::from_eta(eta);
    const stratum::AlphaPrimeTable<float> table(boundary);
    std::printf("eta = %.1f, A = %.6f (Jensen F_dr fit), exact-F_dr A = %.6f\n\n", double(eta), double(boundary.A),
                double(stratum::dipole_A(eta, stratum::DiffuseFresnel::exact)));
    std::printf("%-10s %-3s %9s %9s %9s %10s %12s %12s\n", "material", "ch", "sigma_a", "sigma_s'", "alpha'", "R_d",
                "ld (mm)", "alpha'(R_d)");
    const char* channel[3] = {"R", "G", "B"};
    for (const Material& m : materials) {
        // The pleasant RGB call site: one Dipole<float> per channel.
        const auto dipoles = stratum::make_dipoles<float, 3>(m.sigma_a, m.sigma_s_prime, eta);
        for (std::size_t c = 0; c < 3; ++c) {
            const auto& d = dipoles[c];
            // What a shader does with an artist's colour: R_d -> alpha' (here through the table).
            std::printf("%-10s %-3s %9.4f %9.3f %9.6f %10.6f %12.4f %12.6f\n", c == 0 ? m.name : "", channel[c],
                        double(d.sigma_a()), double(d.sigma_s_prime()), double(d.alpha_prime()),
                        double(d.total_reflectance()), double(d.diffuse_mean_free_path()),
                        double(table(d.total_reflectance())));
        }
    }

    write_svg("dipole_profiles.svg");
    std::printf("\nwrote dipole_profiles.svg (R_d(r) of skin1 and marble, per channel)\n");

    // The table a shader embeds: alpha' at R_d = i / (n - 1), uniform in R_d so the shader indexes it
    // linearly, computed by the exact inversion in double. Its linear-interpolation error is measured here.
    const auto b = stratum::DipoleBoundary<double>::from_eta(1.3);
    std::vector<double> alpha(static_cast<std::size_t>(entries));
    for (int i = 0; i < entries; ++i)
        alpha[static_cast<std::size_t>(i)] = stratum::alpha_prime_from_reflectance(double(i) / (entries - 1), b);
    double worst = 0;
    for (int i = 0; i <= 100000; ++i) {
        const double rd = i / 100000.0, x = rd * (entries - 1);
        const auto j = std::min(static_cast<std::size_t>(x), static_cast<std::size_t>(entries - 2));
        const double u = x - double(j), lerp = alpha[j] + u * (alpha[j + 1] - alpha[j]);
        worst = std::fmax(worst, std::fabs(lerp - stratum::alpha_prime_from_reflectance(rd, b)));
    }
    std::printf("\n// alpha'(R_d) for eta = 1.3 (Jensen F_dr fit), R_d = i / %d; linear interpolation error <= %.2g\n",
                entries - 1, worst);
    std::printf("const float alpha_prime_table[%d] = {", entries);
    for (int i = 0; i < entries; ++i) {
        char literal[32];
        std::snprintf(literal, sizeof literal, "%.9g", alpha[static_cast<std::size_t>(i)]);
        const bool has_point = std::string(literal).find_first_of(".e") != std::string::npos;
        std::printf("%s%s%sf%s", i % 6 == 0 ? "\n    " : "", literal, has_point ? "" : ".0",
                    i + 1 < entries ? ", " : "");
    }
    std::printf("\n};\n");
    return 0;
}
