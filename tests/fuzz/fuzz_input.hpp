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

/// Aborts (which libFuzzer reports with the input) when a promise of the library is broken.
inline void require(bool ok, const char* what) {
    if (!ok) {
        std::fprintf(stderr, "stratum fuzz: broken promise: %s\n", what);
        std::abort();
    }
}

}  // namespace stratum_fuzz
