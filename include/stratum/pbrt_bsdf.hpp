// stratum/pbrt_bsdf.hpp -- pbrt-v3's tabulated BSDF file, the ".bsdf" that its FourierBSDF material reads and
// layerlab writes ("SCATFUN", format version 1): build one from a TabulatedBSDF, write it, read it back, and
// evaluate it as pbrt-v3 does, so that a layered material made here renders in pbrt-v3 unchanged:
//   Material "fourier" "string bsdffile" "skin.bsdf"
//
// The file (little-endian; docs/physics.md section 9 gives the provenance of each field):
//   header, 64 bytes: char[7] "SCATFUN", uint8 version = 1, uint32 flags = 1 (a BSDF), int32 nMu, nCoeffs, mMax,
//     nChannels (1: luminance; 3: luminance Y, red, blue, green following from them), nBases = 1, nMetadataBytes = 0, nParameters = 0, nParameterValues = 0,
//     float eta (index below / index above), float alpha[2] = 0, float unused[2] = 0;
//   float mu[nMu]: cosines ascending in [-1, 1];
//   float cdf[nMu * nMu]: per row o, the running integral over mu_i of a_0(mu_i, mu_o) along the Catmull-Rom spline;
//   int32 {offset, length}[nMu * nMu]: the series of pair (i, o) is coeffs[offset .. offset + length);
//   float coeffs[nCoeffs].
// Pair (i, o) = index o nMu + i (with 3 channels its series are Y, R, B one after another, each of its length), with
// mu_i = cos(-wi) and mu_o = cos(wo) in pbrt-v3's FourierBSDF::f(wo, wi); reflection where mu_i mu_o < 0. Its series
// is that of f |mu_i| in cos(k phi), phi the azimuth between -wi and wo, with f what pbrt-v3 returns in importance
// transport, where wo points to where a light particle came from: f(wo -> wi), light arriving from wo. In radiance
// transport (a camera path: wi towards the light) pbrt-v3 multiplies transmission by eta^2 (eta = 1 / eta_file
// where mu_i > 0, eta_file where mu_i < 0), which by generalized reciprocity, f(a -> b) / n_b^2 = f(b -> a) / n_a^2,
// turns it into f(wi -> wo). So a transmitted pair holds this library's f(w_i -> w_o) (light from the direction
// w_i with cos(-w_i) = mu_i) times (n_i / n_o)^2: 1 / eta_file^2 for light from above, eta_file^2 from below.
// (Holding f(w_i -> w_o) itself, as an earlier version did, a light particle crossing a 1 | 1.5 layer upwards in
// pbrt-v3 left with 1.79 times the energy it brought: found by review.)
// Not representable in this format: deltas (a smooth top's mirror reflection, the direct beam between specular
// faces): they are left out, as pbrt-v3's FourierBSDF is glossy only.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <istream>
#include <ostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "detail/math.hpp"
#include "detail/validate.hpp"
#include "tabulated_bsdf.hpp"
#include "vec3.hpp"

namespace stratum {

/// The content of a pbrt-v3 ".bsdf" file (see the header comment for the meaning of each field).
struct PbrtBsdfTable {
    /// pbrt-v3's luminance of linear RGB, and its inverse for green (src/core/reflection.cpp, FourierBSDF::f).
    static constexpr double y_red = 0.212671, y_green = 0.715160, y_blue = 0.072169;
    int channels = 1;  // 1 (Y) or 3 (Y, R, B)
    float eta = 1;
    std::vector<float> mu;
    std::vector<float> cdf;
    std::vector<std::int32_t> offset, length;
    std::vector<float> coeffs;

    int size() const noexcept { return static_cast<int>(mu.size()); }
    int max_order() const noexcept {
        std::int32_t m = 0;
        for (std::int32_t l : length) m = l > m ? l : m;
        return static_cast<int>(m);
    }

    /// f(wi -> wo) for light arriving from wi, seen from wo (this library's argument order and importance
    /// convention), as pbrt-v3's FourierBSDF::f(wo, wi) evaluates this table for a camera path (radiance
    /// transport): Catmull-Rom weights in mu_i = -wi.z and mu_o = wo.z on the grid, the interpolated series,
    /// max(0, .) / |mu_i|, times eta^2 for transmission (the header comment); the luminance Y. With 3 channels and
    /// rgb given, also red, green (1.39829 Y - 0.100913 B - 0.297375 R, as pbrt-v3 forms it) and blue, each >= 0.
    /// 0 outside the grid. Allocation-free (each of the 16 pairs' series summed at phi, then weighted).
    double eval(Vec3<double> wi, Vec3<double> wo, double* rgb = nullptr) const noexcept;
};

namespace detail {

// Weights of Catmull-Rom interpolation on the non-uniform ascending nodes x[0..n-1] at u, on the interval of the
// last node <= u: cubic Hermite with slopes (f_j+1 - f_j-1) / (x_j+1 - x_j-1), one-sided at the ends. Returns
// the first of the four nodes (some of whose weights may be 0); false if u is outside [x_0, x_n-1].
inline bool catmull_rom_weights(const std::vector<float>& x, double u, int& first, double w[4]) {
    const int n = static_cast<int>(x.size());
    if (n < 2 || !(u >= x.front() && u <= x.back())) return false;
    int lo = 0, hi = n - 1;  // the last node <= u (u = x_n-1: the last interval)
    while (hi - lo > 1) {
        const int mid = (lo + hi) / 2;
        if (x[static_cast<std::size_t>(mid)] <= u) lo = mid; else hi = mid;
    }
    const int j = lo;
    const double x0 = x[static_cast<std::size_t>(j)], x1 = x[static_cast<std::size_t>(j + 1)], h = x1 - x0;
    const double t = h > 0 ? (u - x0) / h : 0, t2 = t * t, t3 = t2 * t;
    const double h10 = t3 - 2 * t2 + t, h11 = t3 - t2;
    first = j - 1;
    w[0] = 0;
    w[1] = 2 * t3 - 3 * t2 + 1;
    w[2] = 3 * t2 - 2 * t3;
    w[3] = 0;
    if (j > 0) {
        const double s = h10 * h / (x1 - x[static_cast<std::size_t>(j - 1)]);
        w[0] -= s;
        w[2] += s;
    } else {
        w[1] -= h10;
        w[2] += h10;
    }
    if (j + 2 < n) {
        const double s = h11 * h / (x[static_cast<std::size_t>(j + 2)] - x0);
        w[1] -= s;
        w[3] += s;
    } else {
        w[1] -= h11;
        w[2] += h11;
    }
    return true;
}

// int over [x_0, x_j] of the Catmull-Rom spline through f on the nodes x, for every j (the cdf of a row).
inline void catmull_rom_running_integral(const std::vector<float>& x, const float* f, float* out) {
    const std::size_t n = x.size();
    double sum = 0;
    out[0] = 0;
    for (std::size_t j = 0; j + 1 < n; ++j) {
        const double x0 = x[j], x1 = x[j + 1], h = x1 - x0, f0 = f[j], f1 = f[j + 1];
        const double d0 = j > 0 ? h * (f1 - f[j - 1]) / (x1 - x[j - 1]) : f1 - f0;
        const double d1 = j + 2 < n ? h * (f[j + 2] - f0) / (x[j + 2] - x0) : f1 - f0;
        sum += ((d0 - d1) / 12 + (f0 + f1) / 2) * h;
        out[j + 1] = static_cast<float>(sum);
    }
}

// The Fourier coefficients (series in cos(k phi)) of a rough interface's BRDF between the light at cosine mu_l and
// the viewer at mu_o, by the periodic trapezoidal rule with 2 max_order points (spectrally accurate for the
// smooth lobe); `cosines` holds cos(2 pi k j / n) at [k n + j]. Returns the length after dropping trailing terms
// below 1e-7 of the largest.
template <class Real>
int surface_coefficients(const RoughDielectric<Real>& surface, double mu_l, double mu_o, double* out, int max_order,
                         const std::vector<double>& cosines) {
    const int n = 2 * max_order;
    std::vector<double> f(static_cast<std::size_t>(n));
    const Vec3<Real> wi = spherical_direction(static_cast<Real>(mu_l), Real(0));
    for (int j = 0; j < n; ++j) {
        const double phi = 2 * pi_v<double> * j / n;  // the azimuth between -wi and wo
        f[static_cast<std::size_t>(j)] =
            static_cast<double>(surface.brdf(wi, spherical_direction(static_cast<Real>(mu_o), static_cast<Real>(pi_v<double> + phi))));
    }
    double largest = 0;
    for (int k = 0; k < max_order; ++k) {
        double s = 0;
        for (int j = 0; j < n; ++j) s += f[static_cast<std::size_t>(j)] * cosines[static_cast<std::size_t>(k * n + j)];
        out[k] = s * (k == 0 ? 1.0 : 2.0) / n;
        largest = std::fmax(largest, std::fabs(out[k]));
    }
    int len = max_order;
    while (len > 0 && std::fabs(out[len - 1]) <= 1e-7 * largest) --len;
    return len;
}

}  // namespace detail

inline double PbrtBsdfTable::eval(Vec3<double> wi, Vec3<double> wo, double* rgb) const noexcept {
    if (rgb) rgb[0] = rgb[1] = rgb[2] = 0;
    const double mu_i = -wi.z, mu_o = wo.z;
    int fi = 0, fo = 0;
    double wgt_i[4], wgt_o[4];
    if (!detail::catmull_rom_weights(mu, mu_i, fi, wgt_i) || !detail::catmull_rom_weights(mu, mu_o, fo, wgt_o) || mu_i == 0)
        return 0;
    // cos(phi) between the projections of -wi and wo (1 when either is along the normal)
    const double ri = std::hypot(wi.x, wi.y), ro = std::hypot(wo.x, wo.y);
    const double x = ri > 0 && ro > 0 ? std::fmin(std::fmax(-(wi.x * wo.x + wi.y * wo.y) / (ri * ro), -1.0), 1.0) : 1.0;
    // The interpolated series at phi, per channel: each pair's series summed at phi (cos(k phi) by the recurrence
    // cos((k + 1) phi) = 2 x cos(k phi) - cos((k - 1) phi)), weighted: the same as summing the interpolated one.
    const int n = size();
    double value[3] = {0, 0, 0};
    for (int b = 0; b < 4; ++b)
        for (int c = 0; c < 4; ++c) {
            const double w = wgt_i[c] * wgt_o[b];
            if (w == 0 || fo + b < 0 || fi + c < 0) continue;
            const std::size_t p = static_cast<std::size_t>((fo + b) * n + fi + c);
            for (int ch = 0; ch < channels; ++ch) {
                const float* a = coeffs.data() + offset[p] + ch * length[p];
                double sum = 0, previous = x, current = 1;  // cos(-phi), cos(0)
                for (int k = 0; k < length[p]; ++k) {
                    sum += static_cast<double>(a[k]) * current;
                    const double next = 2 * x * current - previous;
                    previous = current;
                    current = next;
                }
                value[ch] += w * sum;
            }
        }
    double scale = 1 / std::fabs(mu_i);
    if (mu_i * mu_o > 0) {  // transmission: pbrt-v3's factor in radiance transport
        const double e = mu_i > 0 ? 1 / static_cast<double>(eta) : static_cast<double>(eta);
        scale *= e * e;
    }
    const double y = value[0] > 0 ? value[0] * scale : 0;
    if (rgb && channels == 3) {
        const double r = value[1] * scale, bl = value[2] * scale;
        rgb[0] = std::fmax(r, 0.0);
        rgb[1] = std::fmax(1.39829 * y - 0.100913 * bl - 0.297375 * r, 0.0);
        rgb[2] = std::fmax(bl, 0.0);
    }
    return y;
}

/// The pbrt-v3 table of `table`: its grid of cosines mirrored to [-1, 1] with 0 twice (pairs on a 0 node are empty,
/// so that pbrt's interpolation never mixes the hemispheres, as layerlab's files do), its tabulated lobes converted
/// to the series of f |mu_i| (transmission times (n_i / n_o)^2: the header comment), the rough top's reflection
/// added as its own series, light from below from the table's second side (none for a one-sided table), eta =
/// eta_below / eta_above. Deltas are left out. A table of three channels (linear red, green, blue) gives a file of
/// three (pbrt-v3's Y, R, B); any other count, the table's luminance alone.
template <class Real>
PbrtBsdfTable pbrt_bsdf_table(const TabulatedBSDF<Real>& table) {
    PbrtBsdfTable out;
    const bool rgb = table.channels() == 3;
    out.channels = rgb ? 3 : 1;
    out.eta = static_cast<float>(table.eta_below() / table.eta_above());
    const std::vector<Real> grid = table.grid_cosines();
    const int m = static_cast<int>(grid.size()), n = 2 * m;
    for (int j = m - 1; j >= 0; --j) out.mu.push_back(-static_cast<float>(grid[static_cast<std::size_t>(j)]));
    for (int j = 0; j < m; ++j) out.mu.push_back(static_cast<float>(grid[static_cast<std::size_t>(j)]));
    out.mu[static_cast<std::size_t>(m - 1)] = 0.0f;  // -0 as 0
    const int cap = TabulatedBSDF<Real>::max_order, surface_modes = cap / 2;
    std::vector<double> cosines(static_cast<std::size_t>(2 * surface_modes * surface_modes));
    for (int k = 0; k < surface_modes; ++k)
        for (int j = 0; j < 2 * surface_modes; ++j)
            cosines[static_cast<std::size_t>(k * 2 * surface_modes + j)] = std::cos(detail::pi_v<double> * k * j / surface_modes);
    std::vector<Real> a(static_cast<std::size_t>(cap));
    std::vector<double> s(static_cast<std::size_t>(cap)), b(static_cast<std::size_t>(3 * cap));
    out.offset.assign(static_cast<std::size_t>(n) * static_cast<std::size_t>(n), 0);
    out.length.assign(out.offset.size(), 0);
    for (int o = 0; o < n; ++o)
        for (int i = 0; i < n; ++i) {
            const std::size_t p = static_cast<std::size_t>(o * n + i);
            out.offset[p] = static_cast<std::int32_t>(out.coeffs.size());
            const double mu_i = out.mu[static_cast<std::size_t>(i)], mu_o = out.mu[static_cast<std::size_t>(o)];
            if (mu_i == 0 || mu_o == 0) continue;
            const bool from_below = mu_i > 0, transmitted = mu_i * mu_o > 0;
            const double ai = std::fabs(mu_i), ao = std::fabs(mu_o);
            // (n_i / n_o)^2 for a transmitted pair (the header comment)
            const double eta = static_cast<double>(table.eta_below()) / static_cast<double>(table.eta_above());
            const double reciprocity = !transmitted ? 1.0 : from_below ? eta * eta : 1 / (eta * eta);
            // Tabulated: the series of f |mu_o|, times |mu_i| / |mu_o|; the grid's own nodes, so these are stored
            // values. b holds the channels' series one after another (at k, cap + k, 2 cap + k): the luminance, or
            // red, green, blue.
            std::fill(b.begin(), b.end(), 0.0);
            int len = 0;
            for (int ch = 0; ch < (rgb ? 3 : 1); ++ch) {
                const int lt = table.coefficients(from_below, transmitted, static_cast<Real>(ai), static_cast<Real>(ao),
                                                  a.data(), rgb ? ch : -1);
                for (int k = 0; k < lt; ++k)
                    b[static_cast<std::size_t>(ch * cap + k)] = static_cast<double>(a[static_cast<std::size_t>(k)]) * ai / ao * reciprocity;
                len = lt > len ? lt : len;
            }
            const auto& surface = table.surface(from_below);
            if (!transmitted && surface) {  // the same for every channel
                const int ls = detail::surface_coefficients(*surface, ai, ao, s.data(), surface_modes, cosines);
                for (int ch = 0; ch < (rgb ? 3 : 1); ++ch)
                    for (int k = 0; k < ls; ++k) b[static_cast<std::size_t>(ch * cap + k)] += s[static_cast<std::size_t>(k)] * ai;
                len = ls > len ? ls : len;
            }
            if (rgb) {  // write Y, R, B
                for (int k = 0; k < len; ++k) {
                    const std::size_t r = static_cast<std::size_t>(k), g = r + static_cast<std::size_t>(cap), bl = g + static_cast<std::size_t>(cap);
                    out.coeffs.push_back(static_cast<float>(PbrtBsdfTable::y_red * b[r] + PbrtBsdfTable::y_green * b[g] +
                                                            PbrtBsdfTable::y_blue * b[bl]));
                }
                for (int k = 0; k < len; ++k) out.coeffs.push_back(static_cast<float>(b[static_cast<std::size_t>(k)]));
                for (int k = 0; k < len; ++k) out.coeffs.push_back(static_cast<float>(b[static_cast<std::size_t>(2 * cap + k)]));
            } else {
                for (int k = 0; k < len; ++k) out.coeffs.push_back(static_cast<float>(b[static_cast<std::size_t>(k)]));
            }
            out.length[p] = static_cast<std::int32_t>(len);
        }
    out.cdf.assign(out.offset.size(), 0.0f);
    std::vector<float> a0(static_cast<std::size_t>(n));
    for (int o = 0; o < n; ++o) {
        for (int i = 0; i < n; ++i) {
            const std::size_t p = static_cast<std::size_t>(o * n + i);
            a0[static_cast<std::size_t>(i)] = out.length[p] > 0 ? out.coeffs[static_cast<std::size_t>(out.offset[p])] : 0.0f;
        }
        detail::catmull_rom_running_integral(out.mu, a0.data(), out.cdf.data() + static_cast<std::size_t>(o * n));
    }
    return out;
}

namespace detail {

inline void put_bytes(std::ostream& out, const void* data, std::size_t n) {
    // The format is little-endian; so is every host this library targets (checked where it is read).
    out.write(static_cast<const char*>(data), static_cast<std::streamsize>(n));
}
inline void get_bytes(std::istream& in, void* data, std::size_t n) {
    in.read(static_cast<char*>(data), static_cast<std::streamsize>(n));
    if (!in) detail::fail_runtime_error("stratum: pbrt .bsdf file: truncated");
}
// `count` values of 4 bytes appended to v in chunks of 2^20, so that a header claiming more than the file holds fails
// at the file's end having allocated no more than it read (a 52-byte file claiming 2^31 - 1 coefficients allocated
// 8.6 GB before "truncated", one of 64 bytes claiming nMu = 4096 about 200 MB; found by review sweeps).
template <class T>
void get_array(std::istream& in, std::vector<T>& v, std::size_t count) {
    static_assert(sizeof(T) == 4, "the file's values are 4 bytes");
    const std::size_t first = v.size(), chunk = std::size_t(1) << 20;
    for (std::size_t done = 0; done < count;) {
        const std::size_t step = std::min(chunk, count - done);
        v.resize(first + done + step);
        get_bytes(in, v.data() + first + done, 4 * step);
        done += step;
    }
}
inline bool little_endian() noexcept {
    const std::uint32_t one = 1;
    unsigned char c;
    std::memcpy(&c, &one, 1);
    return c == 1;
}

}  // namespace detail

/// Writes `table` as a pbrt-v3 ".bsdf" file. Throws std::runtime_error if the stream fails (or the host is
/// big-endian: the format is little-endian).
inline void write_pbrt_bsdf(std::ostream& out, const PbrtBsdfTable& table) {
    if (!detail::little_endian()) detail::fail_runtime_error("stratum: pbrt .bsdf files are little-endian; this host is not");
    const std::int32_t n = table.size();
    const char magic[8] = {'S', 'C', 'A', 'T', 'F', 'U', 'N', 1};
    const std::uint32_t flags = 1;
    const std::int32_t ints[8] = {n, static_cast<std::int32_t>(table.coeffs.size()), table.max_order(), table.channels, 1, 0, 0, 0};
    const float floats[5] = {table.eta, 0, 0, 0, 0};
    detail::put_bytes(out, magic, 8);
    detail::put_bytes(out, &flags, 4);
    detail::put_bytes(out, ints, sizeof ints);
    detail::put_bytes(out, floats, sizeof floats);
    detail::put_bytes(out, table.mu.data(), 4 * table.mu.size());
    detail::put_bytes(out, table.cdf.data(), 4 * table.cdf.size());
    for (std::size_t p = 0; p < table.offset.size(); ++p) {
        detail::put_bytes(out, &table.offset[p], 4);
        detail::put_bytes(out, &table.length[p], 4);
    }
    detail::put_bytes(out, table.coeffs.data(), 4 * table.coeffs.size());
    if (!out) detail::fail_runtime_error("stratum: pbrt .bsdf file: write failed");
}
inline void write_pbrt_bsdf(const std::string& path, const PbrtBsdfTable& table) {
    std::ofstream out(path, std::ios::binary);
    if (!out) detail::fail_runtime_error("stratum: cannot open " + path + " for writing");
    write_pbrt_bsdf(out, table);
}

/// Reads a pbrt-v3 ".bsdf" file with the checks pbrt-v3 makes (identifier and version 1, flags 1, one basis, 1 or 3
/// channels, no parameters). Throws std::runtime_error naming what is wrong.
inline PbrtBsdfTable read_pbrt_bsdf(std::istream& in) {
    if (!detail::little_endian()) detail::fail_runtime_error("stratum: pbrt .bsdf files are little-endian; this host is not");
    char magic[8];
    std::uint32_t flags = 0;
    std::int32_t ints[8];
    float floats[5];
    detail::get_bytes(in, magic, 8);
    if (std::memcmp(magic, "SCATFUN\x01", 8) != 0) detail::fail_runtime_error("stratum: not a pbrt .bsdf file of version 1");
    detail::get_bytes(in, &flags, 4);
    detail::get_bytes(in, ints, sizeof ints);
    detail::get_bytes(in, floats, sizeof floats);
    const std::int32_t n = ints[0], n_coeffs = ints[1], channels = ints[3], bases = ints[4];
    if (flags != 1) detail::fail_runtime_error("stratum: pbrt .bsdf file: flags = " + std::to_string(flags) + " (1 expected)");
    if (bases != 1 || (channels != 1 && channels != 3))
        detail::fail_runtime_error("stratum: pbrt .bsdf file: " + std::to_string(channels) + " channels and " +
                                 std::to_string(bases) + " bases (1 or 3, and 1, supported)");
    // nMu up to 4096 (16.7 M pairs: far beyond any table; a corrupt header must not allocate without bound).
    if (n < 2 || n > 4096 || n_coeffs < 0 || ints[6] != 0)
        detail::fail_runtime_error("stratum: pbrt .bsdf file: invalid sizes (nMu = " + std::to_string(n) + ")");
    PbrtBsdfTable t;
    t.channels = channels;
    t.eta = floats[0];
    const std::size_t nn = static_cast<std::size_t>(n) * static_cast<std::size_t>(n);
    detail::get_array(in, t.mu, static_cast<std::size_t>(n));
    for (std::size_t j = 0; j < t.mu.size(); ++j)
        if (!(t.mu[j] >= -1 && t.mu[j] <= 1) || (j > 0 && !(t.mu[j] >= t.mu[j - 1])))
            detail::fail_runtime_error("stratum: pbrt .bsdf file: the cosines are not ascending in [-1, 1]");
    detail::get_array(in, t.cdf, nn);
    std::vector<std::int32_t> pairs;  // offset and length, interleaved, a chunk at a time (no second copy of all)
    for (std::size_t done = 0; done < nn;) {
        const std::size_t step = std::min(std::size_t(1) << 19, nn - done);
        pairs.clear();
        detail::get_array(in, pairs, 2 * step);
        for (std::size_t p = 0; p < step; ++p) {
            const std::int32_t offset = pairs[2 * p], length = pairs[2 * p + 1];
            if (offset < 0 || length < 0 || length > n_coeffs / channels || offset > n_coeffs - channels * length)
                detail::fail_runtime_error("stratum: pbrt .bsdf file: a series outside the coefficients");
            t.offset.push_back(offset);
            t.length.push_back(length);
        }
        done += step;
    }
    detail::get_array(in, t.coeffs, static_cast<std::size_t>(n_coeffs));
    return t;
}
inline PbrtBsdfTable read_pbrt_bsdf(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) detail::fail_runtime_error("stratum: cannot open " + path);
    return read_pbrt_bsdf(in);
}

}  // namespace stratum
