// Time and accuracy of Gauss-Legendre rule generation: stratum::gauss_legendre(_half) versus GSL's
// gsl_integration_glfixed_table_alloc, for n in {8, 32, 128, 1024, 10000}. Errors in ulp against the
// __float128 references of tests/data/gauss_legendre_reference.txt (all nodes for n <= 1024, a sample
// of 832 nodes for n = 10000). Times are process CPU time per rule (the machine may be shared).
// GSL returns stored tables for some n (8, 32, 128, 1024 among them) and computes the others (10000).
// The half-range rule from GSL is gsl_integration_glfixed_point on [0, 1].
#include <gsl/gsl_integration.h>

#include <stratum/quadrature.hpp>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace {

struct Ref {
    int i;
    double x, w, lo, hi;
};

std::map<int, std::vector<Ref>> read_references() {
    std::map<int, std::vector<Ref>> t;
    std::ifstream in(STRATUM_REFERENCE_FILE);
    std::string line;
    std::vector<Ref>* rows = nullptr;
    while (std::getline(in, line)) {
        if (line.empty() || line[0] == '#') continue;
        std::istringstream f(line);
        if (line[0] == 'n') {
            std::string tag;
            int n = 0;
            f >> tag >> n;
            rows = &t[n];
            continue;
        }
        std::string a, b, c, d;
        Ref r{};
        f >> r.i >> a >> b >> c >> d;
        r.x = std::strtod(a.c_str(), nullptr);
        r.w = std::strtod(b.c_str(), nullptr);
        r.lo = std::strtod(c.c_str(), nullptr);
        r.hi = std::strtod(d.c_str(), nullptr);
        rows->push_back(r);
    }
    return t;
}

std::int64_t ulps(double a, double b) {
    std::int64_t ia, ib;
    std::memcpy(&ia, &a, 8);
    std::memcpy(&ib, &b, 8);
    if (ia < 0) ia = INT64_MIN - ia;
    if (ib < 0) ib = INT64_MIN - ib;
    return ia > ib ? ia - ib : ib - ia;
}

double cpu_seconds() {
    timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// CPU time per call of f, repeated for at least 0.3 s.
template <class F>
double time_per_call(F f) {
    long reps = 0;
    const double t0 = cpu_seconds();
    double t = t0;
    do {
        f();
        ++reps;
        t = cpu_seconds();
    } while (t - t0 < 0.3);
    return (t - t0) / static_cast<double>(reps);
}

struct Stat {
    std::int64_t max = 0;
    double sum = 0;
    long count = 0;
    void add(std::int64_t u) {
        max = u > max ? u : max;
        sum += static_cast<double>(u);
        ++count;
    }
};

void print(const char* what, const Stat& s) {
    std::printf("  %-13s max = %lld ulp (mean = %.3g ulp)", what, static_cast<long long>(s.max),
                s.sum / static_cast<double>(s.count));
}

}  // namespace

int main() {
    const auto refs = read_references();
    std::printf("%-8s %-8s %12s   accuracy vs __float128 references\n", "n", "library", "time/rule");
    for (int n : {8, 32, 128, 1024, 10000}) {
        const std::vector<Ref>& ref = refs.at(n);
        // stratum
        const double ts = time_per_call([n] {
            volatile auto q = stratum::gauss_legendre<double>(n).nodes.size();
            (void)q;
        });
        const double tsh = time_per_call([n] {
            volatile auto q = stratum::gauss_legendre_half<double>(n).nodes.size();
            (void)q;
        });
        const auto q = stratum::gauss_legendre<double>(n);
        const auto h = stratum::gauss_legendre_half<double>(n);
        Stat sx, sw, sh, shw;
        for (const Ref& r : ref) {
            const auto i = static_cast<std::size_t>(r.i), m = static_cast<std::size_t>(n - 1 - r.i);
            sx.add(ulps(q.nodes[i], r.x));
            sx.add(ulps(q.nodes[m], -r.x));
            sw.add(ulps(q.weights[i], r.w));
            sh.add(ulps(h.nodes[i], r.hi));
            sh.add(ulps(h.nodes[m], r.lo));
            shw.add(ulps(h.weights[i], r.w / 2));
        }
        std::printf("%-8d %-8s %9.2f us  (half: %.2f us)\n", n, "stratum", ts * 1e6, tsh * 1e6);
        print("nodes", sx);
        print("weights", sw);
        std::printf("\n");
        print("half nodes", sh);
        print("half weights", shw);
        std::printf("\n");

        // GSL
        const double tg = time_per_call([n] {
            gsl_integration_glfixed_table* t = gsl_integration_glfixed_table_alloc(static_cast<std::size_t>(n));
            gsl_integration_glfixed_table_free(t);
        });
        gsl_integration_glfixed_table* t = gsl_integration_glfixed_table_alloc(static_cast<std::size_t>(n));
        Stat gx, gw, gh, ghw;
        for (const Ref& r : ref) {
            double x, w, xh, wh;
            gsl_integration_glfixed_point(-1, 1, static_cast<std::size_t>(r.i), &x, &w, t);
            gx.add(ulps(x, r.x));
            gw.add(ulps(w, r.w));
            gsl_integration_glfixed_point(-1, 1, static_cast<std::size_t>(n - 1 - r.i), &x, &w, t);
            gx.add(ulps(x, -r.x));
            gsl_integration_glfixed_point(0, 1, static_cast<std::size_t>(r.i), &xh, &wh, t);
            gh.add(ulps(xh, r.hi));
            ghw.add(ulps(wh, r.w / 2));
            gsl_integration_glfixed_point(0, 1, static_cast<std::size_t>(n - 1 - r.i), &xh, &wh, t);
            gh.add(ulps(xh, r.lo));
        }
        gsl_integration_glfixed_table_free(t);
        std::printf("%-8d %-8s %9.2f us\n", n, "GSL", tg * 1e6);
        print("nodes", gx);
        print("weights", gw);
        std::printf("\n");
        print("half nodes", gh);
        print("half weights", ghw);
        std::printf("\n");
    }
    return 0;
}
