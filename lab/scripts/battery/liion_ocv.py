#!/usr/bin/env python3
"""The Li-ion OCV table `Chemistry::LiIon` ships (src/battery/chemistry.rs; issue 44, the book's pack
page, "Energy at landing"): the full-cell open-circuit voltage of the Sony US-18650 (LiCoO2 /
graphite MCMB) of Ramadass et al. 2004, as (V/cell, energy fraction above 2.90 V) knots.

Source: P. Ramadass, B. Haran, P. M. Gomadam, R. White, B. N. Popov, "Development of First
Principles Capacity Fade Model for Li-Ion Cells", J. Electrochem. Soc. 151 (2004) A196: the
electrodes' open-circuit potentials U_n(x) (graphite) and U_p(y) (LiCoO2) as the paper fits them,
with the electrode capacities (active volume fraction x thickness x maximum concentration) and the
lithium balance of PyBaMM's `Ramadass2004` parameter set (its positive OCP's stretch 1.13
included), charged along that balance to the set's upper cut-off, 4.20 V. Full cell: OCV =
U_p(y) - U_n(x) with lithium conserved as charge is drawn; energy = the integral of OCV over
charge from 4.20 V full to 2.90 V. Not fitted to, nor taken from, ProgPy (the peer it is scored
against).

  liion_ocv.py            # prints the knots as Rust pairs
"""
import numpy as np


def u_n(x):
    return (0.7222 + 0.1387 * x + 0.029 * x ** 0.5 - 0.0172 / x + 0.0019 / x ** 1.5
            + 0.2808 * np.exp(0.9 - 15 * x) - 0.7984 * np.exp(0.4465 * x - 0.4108))


def u_p(y):
    y = 1.13 * y
    return ((-4.656 + 88.669 * y ** 2 - 401.119 * y ** 4 + 342.909 * y ** 6 - 462.471 * y ** 8
             + 433.434 * y ** 10)
            / (-1 + 18.933 * y ** 2 - 79.532 * y ** 4 + 37.311 * y ** 6 - 73.083 * y ** 8
               + 95.96 * y ** 10))


def ramadass2004_table(floor_v=2.90, full_v=4.20, step_v=0.025):
    x0, y0 = 22610.7 / 30555, 25777.5 / 51555  # the set's initial stoichiometries (its balance)
    q_n, q_p = 0.49 * 88e-6 * 30555, 0.59 * 80e-6 * 51555
    s = np.linspace(-0.3, 1.0, 650001)  # charge drawn from that state, fraction of the negative's
    x, y = x0 - s, y0 + s * q_n / q_p
    ok = (x > 1e-3) & (x < 1.0) & (y > 0.3) & (y < 1 / 1.13 - 1e-6)
    v, s = u_p(y[ok]) - u_n(x[ok]), s[ok]
    start = int(np.argmin(abs(v - full_v)))
    v, s = v[start:], s[start:]
    end = int(np.argmax(v < floor_v))
    v, s = v[: end + 1], s[: end + 1]
    assert np.all(np.diff(v) < 0), "the OCV must fall as charge is drawn"
    e = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(s))])
    frac = 1.0 - e / e[-1]
    # knots every 0.025 V, each rounded to 0.01 V (its energy read at the rounded voltage)
    knots = [round(floor_v + step_v * k, 2) for k in range(1, int(round((full_v - floor_v) / step_v)))]
    rows = [(kv, round(float(frac[int(np.argmin(abs(v - kv)))]), 4)) for kv in knots]
    return [(floor_v, 0.0)] + rows + [(full_v, 1.0)]


if __name__ == "__main__":
    t = ramadass2004_table()
    print(f"const LIION: [(f64, f64); {len(t)}] = [")
    print("\n".join(f"    ({v:.2f}, {e}),".replace(", 0.0)", ", 0.0)").replace(", 1.0)", ", 1.0)") for v, e in t))
    print("];")
