// Reads fuzzer bytes as the numbers a user could pass: each value is either a raw double (any bit pattern:
// NaN, infinities, denormals) or, chosen by a selector byte, a value inside the parameter's valid range,
// so that both the validation and the evaluation paths are exercised.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include <stratum/vec3.hpp>

namespace stratum_fuzz {

class Input {
public:
    Input(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}

    std::uint8_t byte() {
        if (pos_ >= size_) return 0;
        return data_[pos_++];
    }
    double raw() {
        double x = 0;
        if (pos_ + sizeof x <= size_) {
            std::memcpy(&x, data_ + pos_, sizeof x);
            pos_ += sizeof x;
        }
        return x;
    }
    /// A value in [lo, hi] from 4 bytes, or (1 time in 4) a raw double.
    double in(double lo, double hi) {
        if ((byte() & 3) == 0) return raw();
        std::uint32_t u = 0;
        for (int i = 0; i < 4; ++i) u = (u << 8) | byte();
        return lo + (hi - lo) * (static_cast<double>(u) / 4294967295.0);
    }
    /// A value log-uniform in [lo, hi] (lo > 0), or a raw double.
    double log_in(double lo, double hi) {
        const double t = in(0, 1);
        if (!(t >= 0 && t <= 1)) return t;
        return lo * std::pow(hi / lo, t);
    }

private:
    const std::uint8_t* data_;
    std::size_t size_;
    std::size_t pos_ = 0;
};

/// A unit vector from a cosine and an azimuth; the cosine may be exactly 0, +-1 or grazing.
inline stratum::Vec3<double> direction(Input& in) {
    double mu = in.in(-1, 1);
    if (!(std::fabs(mu) <= 1)) mu = 0.5;
    switch (in.byte() & 7) {
        case 0: mu = mu < 0 ? -1 : 1; break;
        case 1: mu = std::copysign(1e-300, mu); break;
        case 2: mu = 0; break;
        default: break;
    }
    double phi = in.in(0, 6.283185307179586);
    if (!std::isfinite(phi)) phi = 0;
    const double s = std::sqrt((1 - mu) * (1 + mu));
    return {s * std::cos(phi), s * std::sin(phi), mu};
}

/// A uniform in [0, 1) (0.5 for a raw value outside it).
inline double unit(Input& in) {
    const double u = in.in(0, 1);
    return u >= 0 && u < 1 ? u : 0.5;
}

/// Aborts (which libFuzzer reports with the input) when a promise of the library is broken.
inline void require(bool ok, const char* what) {
    if (!ok) {
        std::fprintf(stderr, "stratum fuzz: broken promise: %s\n", what);
        std::abort();
    }
}

}  // namespace stratum_fuzz
