"""The contact engine against its closed forms: measured errors beside the promised error estimate.

Run: ``python benchmarks/bench_contact_oracles.py [--sizes 64 128 256]`` (about a minute on small grids).

Each row solves one problem with ``solve_contact`` (tol 1e-8, skin E = 1 MPa, nu = 1/2) and prints
the measured error against an independent closed form (Johnson, Contact Mechanics), in the unit the
test suite uses, with the solution's own ``error_estimate`` (a bound on max |p error| / max p):

- Hertz sphere (isolated, 3-D; 0.5 N, R = 10 mm, the grid spanning 3 contact diameters): contact
  radius (disc of equal area) minus a, in grid spacings; the total force; max |p - p_Hertz| / p0.
- Hertz cylinder (isolated, plane strain; 100 N/m, R = 10 mm): half-width error in spacings;
  max |p - p_Hertz| / p0.
- Westergaard (periodic sinusoid, plane strain; one period on n nodes): contact half-width a against
  sin^2(pi a / L) = p_mean / p*, in spacings, at p_mean / p* = 0.01, 0.1, 0.5, 0.9.
- Cattaneo-Mindlin (sphere and cylinder at Q / (mu P) = 0.5, mu = 0.5): stick radius (disc of equal
  area; the half-width in plane strain) against c = a (1 - Q / (mu P))^(1/3) (sphere) and
  a (1 - Q / (mu P))^(1/2) (cylinder), in spacings.
"""

from __future__ import annotations

import argparse
import sys
import warnings

import numpy as np

from tactilab.forward import AccuracyWarning, HalfSpace, solve_contact

E_PA, NU = 1e6, 0.5
E_STAR = E_PA / (1 - NU**2)
SKIN = HalfSpace(E=E_PA, nu=NU)


def _row(name: str, n: int, error: float, unit: str, sol, true_p_error: float | None = None) -> None:
    kept = "" if true_p_error is None else ("yes" if sol.error_estimate >= true_p_error else "NO")
    p_err = "-" if true_p_error is None else f"{true_p_error:.2e}"
    print(f"{name:<34}{n:>6}{error:>12.3g} {unit:<12}{p_err:>12}{sol.error_estimate:>12.2e}{kept:>6}")


def sphere(n: int) -> None:
    force, radius = 0.5, 10e-3
    a = (3 * force * radius / (4 * E_STAR)) ** (1 / 3)
    p0 = 3 * force / (2 * np.pi * a**2)
    dx = 6 * a / n
    x = (np.arange(n) - n // 2) * dx
    yy, xx = np.meshgrid(x, x, indexing="ij")
    r2 = xx**2 + yy**2
    sol = solve_contact(SKIN, r2 / (2 * radius), dx, normal_force=force)
    c = np.sqrt(np.count_nonzero(sol.contact) * dx * dx / np.pi)
    exact = p0 * np.sqrt(np.clip(1 - r2 / a**2, 0, None))
    _row("Hertz sphere: radius", n, (c - a) / dx, "spacings", sol, float(np.abs(sol.pressure - exact).max() / p0))
    _row("Hertz sphere: total force", n, sol.pressure.sum() * dx * dx / force - 1, "relative", sol)
    q = 0.5 * 0.5 * force
    part = solve_contact(SKIN, r2 / (2 * radius), dx, normal_force=force, friction=0.5, condition="partial",
                         tangential_force=(q, 0.0))
    c = np.sqrt(np.count_nonzero(part.stick) * dx * dx / np.pi)
    _row("Cattaneo-Mindlin sphere: c", n, (c - a * 0.5 ** (1 / 3)) / dx, "spacings", part)


def cylinder(n: int) -> None:
    force, radius = 100.0, 10e-3
    a = np.sqrt(4 * force * radius / (np.pi * E_STAR))
    p0 = 2 * force / (np.pi * a)
    dx = 6 * a / n
    x = (np.arange(n) - n // 2) * dx
    sol = solve_contact(SKIN, x**2 / (2 * radius), dx, normal_force=force)
    half = np.count_nonzero(sol.contact) * dx / 2
    exact = p0 * np.sqrt(np.clip(1 - x**2 / a**2, 0, None))
    _row("Hertz cylinder: half-width", n, (half - a) / dx, "spacings", sol,
         float(np.abs(sol.pressure - exact).max() / p0))
    part = solve_contact(SKIN, x**2 / (2 * radius), dx, normal_force=force, friction=0.5, condition="partial",
                         tangential_force=0.25 * force)
    c = np.count_nonzero(part.stick) * dx / 2
    _row("Cattaneo-Mindlin cylinder: c", n, (c - a * np.sqrt(0.5)) / dx, "spacings", part)


def westergaard(n: int, ratio: float) -> None:
    period, amplitude = 1e-3, 5e-6
    p_star = np.pi * E_STAR * amplitude / period
    dx = period / n
    x = (np.arange(n) - n // 2) * dx
    sol = solve_contact(SKIN, -amplitude * np.cos(2 * np.pi * x / period), dx, mean_pressure=ratio * p_star,
                        periodic=True)
    a = period / np.pi * np.arcsin(np.sqrt(ratio))
    half = np.count_nonzero(sol.contact) * dx / 2
    _row(f"Westergaard p/p* = {ratio:g}: a", n, (half - a) / dx, "spacings", sol)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[64, 128, 256], help="grids of the 3-D rows; the "
                        "plane-strain rows use 8 times as many nodes")
    args = parser.parse_args(argv)
    print(f"{'oracle':<34}{'n':>6}{'error':>12} {'unit':<12}{'max|dp|/p0':>12}{'estimate':>12}{'kept':>6}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)  # the coarsest rows warn on purpose
        for n in args.sizes:
            sphere(n)
        for n in args.sizes:
            cylinder(8 * n)
        for ratio in (0.01, 0.1, 0.5, 0.9):
            for n in args.sizes:
                westergaard(8 * n, ratio)
    return 0


if __name__ == "__main__":
    sys.exit(main())
