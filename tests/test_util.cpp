// Tests of the test helpers themselves: a helper that cannot fail would hide every defect it is used for.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>

#include "test_util.hpp"

using stratum_test::ulp_distance;

TEST_CASE("ulp_distance counts representable values between two doubles") {
    const double x = 1.0;
    CHECK(ulp_distance(x, x) == 0);
    CHECK(ulp_distance(x, std::nextafter(x, 2.0)) == 1);
    CHECK(ulp_distance(std::nextafter(x, 0.0), std::nextafter(x, 2.0)) == 2);
    CHECK(ulp_distance(0.0, -0.0) == 0);
    // Across zero: the smallest subnormals on either side are 2 apart.
    const double tiny = std::numeric_limits<double>::denorm_min();
    CHECK(ulp_distance(-tiny, tiny) == 2);
    CHECK(ulp_distance(1.0, std::nan("")) == std::numeric_limits<std::int64_t>::max());
}

TEST_CASE("ulp_distance works for float") {
    const float x = 0.75f;
    CHECK(ulp_distance(x, std::nextafter(x, 1.0f)) == 1);
    CHECK(ulp_distance(-x, std::nextafter(-x, -1.0f)) == 1);
    // 1 and 2 differ by 2^23 floats.
    CHECK(ulp_distance(1.0f, 2.0f) == (std::int64_t{1} << 23));
}

TEST_CASE("pooled_chi_square sums Pearson terms and pools sparse bins") {
    // Threshold 12: full bins 30 and 15 give (28-30)^2/30 + 0; the sparse bins (expected 10 + 5 = 15) are
    // pooled: (12 + 9 - 15)^2 / 15 = 2.4.
    const auto c = stratum_test::pooled_chi_square({10, 30, 5, 15}, {12, 28, 9, 15}, 12);
    CHECK(c.bins == 3);
    CHECK(std::fabs(c.value - (4.0 / 30 + 2.4)) < 1e-14);
    // A pool expecting fewer than the threshold is dropped.
    CHECK(stratum_test::pooled_chi_square({10, 2}, {10, 7}, 10).bins == 1);
}
