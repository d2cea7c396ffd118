// render_sphere: a tiny path tracer that renders two spheres under a sky with TabulatedBSDF materials, and writes
// render_sphere.png (and prints what it did). One header (stratum/tabulated_bsdf.hpp) and importance sampling: the
// renderer's side of the library in about a hundred lines.
//
// Left: skin, as Stam's skin layer (n 1 | 1.4, rough top of sigma 0.3, albedo 0.9, g 0.8, e^-tau 0.5) over a
// Lambertian dermis of albedo 0.75 / 0.42 / 0.32 (red / green / blue) in place of Stam's rough bottom face.
// Right: a glazed tile: a smooth coat of index 1.5 (a delta reflection), a thin clear layer, over a red Lambertian
// base. Light: a sky (zenith blue, white horizon, brown ground) and a sun of 1 degree radius.
// Each pixel averages camera paths of one bounce: the camera ray meets a sphere, the BSDF is sampled
// (TransportMode::radiance: wi is the viewer) and the path gathers the sky, and the sun is sampled too, the two
// combined by multiple importance sampling (power heuristic). One table per material holds the three colour
// channels on one grid; its luminance drives sampling.
//
// Usage: render_sphere [width] [samples per pixel]     (defaults 400 and 32; the image is width x width/2)
#include <stratum/tabulated_bsdf.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

#include "png.hpp"

using Real = double;
using V = stratum::Vec3<Real>;

namespace {

struct Rgb {
    Real r = 0, g = 0, b = 0;
};

// The sun: a disk of angular radius 1 degree around sun_direction, of radiance sun_radiance (white).
const V sun_direction = stratum::normalize(V{0.5, 0.6, 0.62});
const Real sun_cos = std::cos(1.0 * 3.14159265358979 / 180), sun_radiance = 6000;
// Density of the sun's uniform cone sampling, per steradian.
const Real sun_pdf = 1 / (2 * 3.14159265358979 * (1 - sun_cos));

bool in_sun(V d) { return stratum::dot(d, sun_direction) >= sun_cos; }

// The sky's radiance in the world direction d (y up), without the sun.
Rgb sky(V d) {
    if (d.y < 0) return {Real(0.25), Real(0.2), Real(0.15)};
    const Real h = std::pow(1 - d.y, 3);
    return {Real(0.3) + Real(0.7) * h, Real(0.5) + Real(0.5) * h, Real(0.9) + Real(0.1) * h};
}

// A direction in the sun's cone, uniformly.
V sample_sun(Real u1, Real u2) {
    const Real c = 1 - u1 * (1 - sun_cos), s = std::sqrt(1 - c * c), phi = 2 * 3.14159265358979 * u2;
    const V a = stratum::normalize(stratum::cross(std::fabs(sun_direction.x) < 0.9 ? V{1, 0, 0} : V{0, 1, 0}, sun_direction));
    const V b = stratum::cross(sun_direction, a);
    return s * std::cos(phi) * a + s * std::sin(phi) * b + c * sun_direction;
}

// A material: red, green and blue on one grid, the luminance (linear sRGB weights) sampled.
using Material = stratum::TabulatedBSDF<Real>;
const std::vector<Real> luminance = {0.2126, 0.7152, 0.0722};

Material skin() {
    stratum::LayerOptions options;
    options.ordinates = 16;
    const stratum::PreparedBoundary<Real> top(stratum::RoughDielectric<Real>(0.3, 1.0, 1.4), options);
    std::vector<stratum::LayeredSurface<Real>> rgb;
    for (Real dermis : {0.75, 0.42, 0.32})
        rgb.push_back(stratum::solve_layer(stratum::Slab<Real>::from_transparency(0.9, 0.8, 0.5), top,
                                           stratum::PreparedBoundary<Real>(stratum::Boundary<Real>::lambertian(dermis, 1.4), options)));
    return Material(rgb, Real(1e-2), luminance);
}

Material glazed_tile() {
    stratum::LayerOptions options;
    options.ordinates = 16;
    std::vector<stratum::LayeredSurface<Real>> rgb;
    for (Real base : {0.7, 0.12, 0.08})
        rgb.push_back(stratum::solve_layer(stratum::Slab<Real>(0.9, 0.0, 0.05), stratum::SmoothDielectric<Real>(1.0, 1.5),
                                           stratum::Boundary<Real>::lambertian(base, 1.5), options));
    return Material(rgb, Real(1e-2), luminance);
}

// f(wi, wo) |wo.z| per channel, wi towards the viewer (local frame).
Rgb throughput(const Material& m, V wi, V wo) {
    Real f[3];
    m.eval(wi, wo, f, stratum::TransportMode::radiance);
    const Real c = std::fabs(wo.z);
    return {c * f[0], c * f[1], c * f[2]};
}

// The radiance leaving the surface towards the viewer (wi, local frame): one BSDF sample and one sun sample.
Rgb shade(const Material& m, V wi, V n, V t, V b, std::mt19937_64& rng) {
    std::uniform_real_distribution<Real> uniform(0, 1);
    Rgb out;
    const auto add = [&out](Rgb f, Real w, Rgb l) {
        out.r += w * f.r * l.r;
        out.g += w * f.g * l.g;
        out.b += w * f.b * l.b;
    };
    const Rgb sun{sun_radiance, sun_radiance, sun_radiance};
    // The BSDF sample: the sky, and the sun where it hits it (weighted against the sun sample's density).
    Real v[3];
    const stratum::BsdfSample<Real> s =
        m.sample(wi, uniform(rng), uniform(rng), uniform(rng), v, stratum::TransportMode::radiance);
    if (s.valid() && s.wo.z > 0) {  // transmitted light is lost under the layer
        const V world = s.wo.x * t + s.wo.y * b + s.wo.z * n;
        const Rgb f{v[0] * s.wo.z, v[1] * s.wo.z, v[2] * s.wo.z};
        add(f, 1 / s.pdf, sky(world));
        // The sun: a delta (the coat's mirror) is the only way to see it there; otherwise weighted against the sun
        // sample's density.
        if (in_sun(world)) add(f, s.delta ? 1 / s.pdf : s.pdf / (s.pdf * s.pdf + sun_pdf * sun_pdf), sun);
    }
    // The sun sample, weighted against the BSDF's density there (power heuristic).
    const V d = sample_sun(uniform(rng), uniform(rng));
    const V wo{stratum::dot(d, t), stratum::dot(d, b), stratum::dot(d, n)};
    if (wo.z > 0) {
        const Real p = m.pdf(wi, wo, stratum::TransportMode::radiance);
        add(throughput(m, wi, wo), sun_pdf / (sun_pdf * sun_pdf + p * p), sun);
    }
    return out;
}

std::uint8_t to_byte(Real x) {  // exposure, then the sRGB curve
    x = std::clamp(x * Real(0.6), Real(0), Real(1));
    x = x <= Real(0.0031308) ? 12.92 * x : 1.055 * std::pow(x, 1 / 2.4) - 0.055;
    return static_cast<std::uint8_t>(std::lround(x * 255));
}

}  // namespace

int main(int argc, char** argv) {
    const int width = argc > 1 ? std::max(16, std::atoi(argv[1])) : 400, height = width / 2;
    const int spp = argc > 2 ? std::max(1, std::atoi(argv[2])) : 32;
    const auto start = std::chrono::steady_clock::now();
    const Material materials[2] = {skin(), glazed_tile()};
    const double build_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::size_t bytes = 0;
    for (const Material& m : materials) bytes += m.memory_bytes();

    // Camera at (0, 0, 6) looking down -z; spheres of radius 1 at x = -1.15 and +1.15.
    const V eye{0, 0, 6};
    const Real centres[2] = {-1.15, 1.15}, half_height = Real(0.22);
    std::vector<std::uint8_t> image(static_cast<std::size_t>(3 * width * height));
    std::mt19937_64 rng(1);
    std::uniform_real_distribution<Real> uniform(0, 1);
    const auto render_start = std::chrono::steady_clock::now();
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            Rgb sum;
            for (int k = 0; k < spp; ++k) {
                const Real px = (2 * (x + uniform(rng)) - width) / height * half_height;
                const Real py = (height - 2 * (y + uniform(rng))) / height * half_height;
                const V d = stratum::normalize(V{px, py, -1});
                Rgb l = sky(d);
                if (in_sun(d)) l = {sun_radiance, sun_radiance, sun_radiance};
                for (int s = 0; s < 2; ++s) {  // the spheres do not overlap in the image: the first hit is the only one
                    const V oc = eye - V{centres[s], 0, 0};
                    const Real bq = stratum::dot(oc, d), disc = bq * bq - (stratum::dot(oc, oc) - 1);
                    if (disc < 0) continue;
                    const V p = eye + (-bq - std::sqrt(disc)) * d;
                    const V n = stratum::normalize(p - V{centres[s], 0, 0});
                    const V t = stratum::normalize(stratum::cross(V{0, 1, 0}, n)), b = stratum::cross(n, t);
                    const V wi{-stratum::dot(d, t), -stratum::dot(d, b), -stratum::dot(d, n)};  // towards the viewer
                    l = shade(materials[s], wi, n, t, b, rng);
                }
                sum.r += l.r;
                sum.g += l.g;
                sum.b += l.b;
            }
            std::uint8_t* px = &image[static_cast<std::size_t>(3 * (y * width + x))];
            px[0] = to_byte(sum.r / spp);
            px[1] = to_byte(sum.g / spp);
            px[2] = to_byte(sum.b / spp);
        }
    const double render_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - render_start).count();
    if (!example::write_png("render_sphere.png", width, height, image)) {
        std::fprintf(stderr, "render_sphere: cannot write render_sphere.png\n");
        return 1;
    }
    std::printf("tables: 2 (red, green, blue on one grid each), %.0f kB, solved and built in %.1f s\n",
                static_cast<double>(bytes) / 1024, build_s);
    std::printf("rendered %d x %d at %d samples per pixel in %.1f s (%.0f ns per camera path)\n", width, height, spp,
                render_s, 1e9 * render_s / (double(width) * height * spp));
    std::printf("wrote render_sphere.png\n");
    return 0;
}
