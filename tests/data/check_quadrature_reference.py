#!/usr/bin/env python3
"""Cross-check of gauss_legendre_reference.txt (written by gen_quadrature_reference.cpp in __float128)
against mpmath at 60 significant digits, for a sample of rules and nodes.

For each sampled node the root of P_n is polished by Newton's method in mpmath, starting from the
file's double, and the weight 2 / ((1 - x^2) P_n'(x)^2) and the half-range ordinates (1 -+ x)/2 are
rounded to double (mpmath rounds to nearest); every value must equal the file's exactly.
Run: /usr/bin/python3 tests/data/check_quadrature_reference.py   (prints "ok" and the count, ~20 s)
"""
import os
import sys

import mpmath as mp

mp.mp.dps = 60
HERE = os.path.dirname(os.path.abspath(__file__))


def read_reference(path):
    rules, n, rows = {}, None, None
    with open(path) as f:
        for line in f:
            if line.startswith("#"):
                continue
            parts = line.split()
            if parts[0] == "n":
                n = int(parts[1])
                rows = rules.setdefault(n, [])
            else:
                rows.append((int(parts[0]), *[float.fromhex(p) for p in parts[1:]]))
    return rules


def legendre_pair(n, x):
    """P_n(x) and P_{n-1}(x) by the three-term recurrence in mpmath."""
    p0, p1 = mp.mpf(1), x
    for l in range(1, n):
        p0, p1 = p1, ((2 * l + 1) * x * p1 - l * p0) / (l + 1)
    return (p1, p0) if n > 1 else (x, mp.mpf(1))


def polished(n, x0):
    x = mp.mpf(x0)
    if x == 0:
        return x
    for _ in range(8):
        pn, pn1 = legendre_pair(n, x)
        dp = n * (pn1 - x * pn) / (1 - x * x)
        x -= pn / dp
    return x


def check(rules, n, rows):
    bad = 0
    for (i, x, w, lo, hi) in rows:
        xr = polished(n, x)
        pn, pn1 = legendre_pair(n, xr)
        dp = n * (pn1 - xr * pn) / (1 - xr * xr)
        wr = 2 / ((1 - xr * xr) * dp * dp)
        want = (float(xr), float(wr), float((1 - xr) / 2), float((1 + xr) / 2))
        if want != (x, w, lo, hi):
            print("mismatch n=%d i=%d: file %r mpmath %r" % (n, i, (x, w, lo, hi), want))
            bad += 1
    return bad


def main():
    rules = read_reference(os.path.join(HERE, "gauss_legendre_reference.txt"))
    bad = count = 0
    for n in list(range(1, 41)) + [64, 100, 127, 128, 199, 200, 256, 333, 512, 1000, 2000, 5000, 10000]:
        rows = rules[n]
        if n > 200:  # sample: both ends and a few interior nodes
            rows = rows[:6] + rows[len(rows) // 2: len(rows) // 2 + 3] + rows[-6:]
        bad += check(rules, n, rows)
        count += len(rows)
    print("ok" if bad == 0 else "FAILED", count, "nodes checked")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
