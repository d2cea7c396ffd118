#!/usr/bin/python3
"""Reference azimuthal Fourier coefficients of the Henyey-Greenstein phase function for
tests/test_henyey_greenstein.cpp. Prints C++ initializer lines; paste them into the test.

Two independent routes, both in mpmath:
 1. "integral": the untruncated coefficient by direct azimuthal integration (4 pi normalization),
        p_k(mu', mu) = (2 - delta_k0) / (2 pi) int_0^{2 pi} 4 pi p(cos gamma(phi)) cos(k phi) dphi,
        cos gamma = mu' mu + sqrt(1 - mu'^2) sqrt(1 - mu^2) cos phi,
    with 40-digit Gauss-Legendre quadrature (mpmath.quad) -- no Legendre functions involved.
 2. "series": the truncated Legendre series sum_{n=k}^{N} (2 - delta_k0)(2n + 1) g^n Lambda_n^k Lambda_n^k
    for k = 200 at the outermost node of a 100-point rule, where sin^k underflows double: the
    normalized functions are built from the explicit seed (-1)^k sqrt((2k)!)/(2^k k!) sin^k and the
    three-term recurrence in 60-digit arithmetic with an unbounded exponent (no scaling needed).
Run: /usr/bin/python3 tests/data/gen_henyey_greenstein.py
"""
import mpmath as mp

mp.mp.dps = 40


def hg4pi(g, c):
    return (1 - g * g) / (1 + g * g - 2 * g * c) ** mp.mpf(1.5)


def coefficient_integral(g, mup, mu, k):
    g, mup, mu = mp.mpf(g), mp.mpf(mup), mp.mpf(mu)
    a = mup * mu
    b = mp.sqrt(1 - mup * mup) * mp.sqrt(1 - mu * mu)
    f = lambda phi: hg4pi(g, a + b * mp.cos(phi)) * mp.cos(k * phi)
    # symmetric in phi -> 2 pi - phi; split [0, pi] geometrically from phi = 0 (where the forward
    # peak of width ~(1 - g) sits) and uniformly elsewhere, so every piece is smooth on its scale
    w = (1 - abs(g)) / 16
    cuts = [mp.mpf(0)]
    while w < mp.pi / 8:
        cuts.append(w)
        w *= 2
    cuts += [x for x in mp.linspace(mp.pi / 8, mp.pi, 8 + 4 * k // 10)]
    val = 2 * mp.quad(f, cuts)
    return (1 if k == 0 else 2) * val / (2 * mp.pi)


def lambdas(k, N, x):
    x = mp.mpf(x)
    s = mp.sqrt((1 - x) * (1 + x))
    seed = (-1) ** k * mp.sqrt(mp.factorial(2 * k)) / (mp.mpf(2) ** k * mp.factorial(k)) * s ** k
    out = {k: seed}
    prev, cur = mp.mpf(0), seed
    for l in range(k + 1, N + 1):
        r = mp.sqrt(mp.mpf((l - k) * (l + k)))
        r1 = mp.sqrt(mp.mpf((l - 1 - k) * (l - 1 + k)))
        prev, cur = cur, ((2 * l - 1) * x * cur - r1 * prev) / r
        out[l] = cur
    return out


def coefficient_series(g, mup, mu, k, N):
    g = mp.mpf(g)
    a, b = lambdas(k, N, mup), lambdas(k, N, mu)
    total = mp.fsum((2 * n + 1) * g ** n * a[n] * b[n] for n in range(k, N + 1))
    return (1 if k == 0 else 2) * total


def main():
    print("// integral: {g, mu', mu, k, p_k}")
    for g in ("0.9", "-0.9", "0.5"):
        for (mup, mu) in (("0.3", "0.7"), ("-0.5", "0.9"), ("0.999", "-0.2"), ("0.8", "0.8")):
            for k in (0, 1, 2, 5, 20):
                v = coefficient_integral(g, mup, mu, k)
                print("{%s, %s, %s, %d, %s}," % (g, mup, mu, k, mp.nstr(v, 22, min_fixed=-1, max_fixed=0)))
    print("// integral, g near 1: {g, mu', mu, k, p_k}")
    for g in ("0.99", "0.999"):
        for (mup, mu) in (("0.3", "0.7"), ("0.8", "0.8"), ("0.5", "0.52"), ("0.999", "-0.2")):
            for k in (0, 1, 2, 5, 20, 100):
                v = coefficient_integral(g, mup, mu, k)
                print("{%s, %s, %s, %d, %s}," % (g, mup, mu, k, mp.nstr(v, 22, min_fixed=-1, max_fixed=0)))
    mp.mp.dps = 60
    x100 = float(mp.findroot(lambda t: mp.legendre(100, t), mp.cos(mp.pi * 0.75 / 100.5)))
    print("// series, N = 2000, x100 = %r: {g, mu', mu, k, p_k}" % x100)
    for (mup, mu) in ((x100, x100), (x100, 0.5), (-x100, 0.5)):
        for k in (200, 1000):
            v = coefficient_series("0.9", mup, mu, k, 2000)
            print("{0.9, %r, %r, %d, %s}," % (mup, mu, k, mp.nstr(v, 22)))


if __name__ == "__main__":
    main()
