"""The speed-accuracy trade on one page: time against TRUE error, from one run, for each job.

Run: ``python benchmarks/bench_tradeoff.py [--quick] [--out docs]``

Writes ``<out>/accuracy.md`` (tables, the figure, the machine load, the command, and which
method to pick for which need) and ``<out>/accuracy.png`` (log-log, time in ms against relative
error, one curve per method). Timings are the minimum over repeats, single FFT thread.

Forward job: a Hertz contact of radius a = 1 mm sliding with friction mu = 0.5 (p0 sqrt(1 - r^2/a^2),
qx = mu p), given to the solver as a continuous load (forward/contact/hertz.py
``HertzContact.load(friction=0.5, condition="sliding", spacing=h, half_width=...)``), all six
stress components at depth a/2 at 34 sensors every a/4 on two lines (y = 0 and y = a/2, |x| <= 2a), on
grids of spacing h = a/4 to a/64. Methods (forced): ``closed_form`` and ``dcfft`` on a grid of
[-2a, 2a]^2 (the load is zero outside it), ``spectral`` on a periodic box of side 16 a (the contact
and its periodic images 16 a apart). True error: max over points and components of |sigma - sigma_ref| / max |sigma_ref|,
with sigma_ref Hamilton's closed form (benchmarks/hamilton_reference.py, written apart from the
solver). Each result's own ``error_estimate`` is shown beside it.

Inversion job: one plane-strain pressure profile (16 nodes, 0.5 mm apart, periodic) seen as
sigma_zz at 0.5 mm depth by a sensor under every node, noise 1 % of the peak signal, Matern-5/2
prior (sd 5 kPa, correlation length 1 mm). Routes: the exact Gaussian posterior on the ``fft``
and ``dense`` paths, the ``iterative`` path (CG, over its tolerance), and MCMC
(``sample_posterior`` on the same Gaussian model, over its step limit). True error: relative L2
distance of the posterior mean (and of the pointwise std) from the exact posterior computed here
with dense numpy algebra, independently of tactilab.inversion.
"""

from __future__ import annotations

import argparse
import datetime
import math
import os
import platform
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from tactilab.forward import HertzContact
from tactilab.forward.halfspace import HalfSpace
from tactilab.inversion import StationaryPrior, gaussian_posterior, halfspace_fourier_operator, sample_posterior

sys.path.insert(0, str(Path(__file__).resolve().parent))
from hamilton_reference import hamilton_stress  # noqa: E402  (benchmarks/ sibling, not a package)

A = 1e-3  # m, contact radius
MU = 0.5
NU = 0.5
E_PA = 1e6
FINGER_RADIUS = 0.01  # m
DEPTH = A / 2
BOX = 16  # spectral periodic box side, in units of a
FORWARD_METHODS = ("closed_form", "dcfft", "spectral")
INVERSION_METHODS = ("fft", "dense", "iterative", "mcmc")
COLORS = {"closed_form": "tab:blue", "dcfft": "tab:orange", "spectral": "tab:green",
          "fft": "tab:green", "dense": "tab:blue", "iterative": "tab:orange", "mcmc": "tab:red"}


# -- forward ------------------------------------------------------------------------------------
def hertz_contact() -> HertzContact:
    """The contact of radius A: F = 4 E* a^3 / (3 R)."""
    e_star = E_PA / (1 - NU**2)
    force = 4 * e_star * A**3 / (3 * FINGER_RADIUS)
    contact = HertzContact(force, FINGER_RADIUS, E_PA, NU)
    assert abs(contact.contact_radius - A) < 1e-12 * A
    return contact


def sensor_points(step: float = A / 4) -> np.ndarray:
    """The sensors: points every a/4 on the lines y = 0 and y = a/2 with |x| <= 2a, shape (34, 2), m.

    The same points on every grid (nodes of every grid from a/4 down), so the errors compare.
    """
    x = np.arange(-8, 9) * step
    return np.concatenate([np.column_stack([x, np.zeros_like(x)]), np.column_stack([x, np.full_like(x, A / 2)])])


def min_time(fun, repeats: int, warm_up: bool = True) -> tuple[float, object]:
    """(min wall time in s over ``repeats`` calls, the last result); one untimed call first."""
    if warm_up:
        fun()
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fun()
        best = min(best, time.perf_counter() - t0)
    return best, out


def forward_rows(per_a=(4, 8, 16, 32, 64), repeats: int = 3, box: int = BOX) -> list[dict]:
    """One row per (method, grid): time, true error vs Hamilton, the result's error estimate."""
    contact = hertz_contact()
    p0 = contact.peak_pressure
    hs = HalfSpace(E_PA, NU)
    rows = []
    pts = sensor_points()
    for m in per_a:
        h = A / m
        ref = hamilton_stress(pts[:, 0], pts[:, 1], DEPTH, a=A, p0=p0, mu=MU, nu=NU)  # (6, n)
        # the contact as a continuous load: the solver samples it and its estimate covers the sampling
        isolated = contact.load(friction=MU, condition="sliding", spacing=h, half_width=2 * A)
        periodic_box = contact.load(friction=MU, condition="sliding", spacing=h, half_width=box * A / 2)
        loads = {"closed_form": isolated, "dcfft": isolated, "spectral": periodic_box}
        for method in FORWARD_METHODS:
            load = loads[method]
            reps = 1 if (method == "closed_form" and m >= 32) else repeats

            def run(load=load, method=method):
                with warnings.catch_warnings():  # a forced method whose estimate exceeds tol warns
                    warnings.simplefilter("ignore")
                    return hs.stress(load, DEPTH, points=pts, method=method, tol=1e-5)

            seconds, res = min_time(run, reps, warm_up=reps > 1)
            got = res.data["stress"].values[0]  # (6, n)
            attrs = res.data.attrs
            rows.append(dict(job="forward", method=method, per_a=m, h=h, grid=load.shape[0], time_ms=1e3 * seconds,
                             error=float(np.abs(got - ref).max() / np.abs(ref).max()),
                             estimate=float(res.error_estimate),
                             method_estimate=float(attrs.get("method_error_estimate", res.error_estimate)),
                             sampling_estimate=float(attrs.get("sampling_error_estimate", 0.0)),
                             covers=str(attrs.get("error_covers", "")), repeats=reps))
    return rows


# -- inversion ----------------------------------------------------------------------------------
class GaussianProfileModel:
    """The linear-Gaussian profile problem as a :class:`tactilab.inversion.PosteriorModel` (pickles)."""

    vectorized = True

    def __init__(self, matrix: np.ndarray, data: np.ndarray, noise_std: float, prior_cov: np.ndarray):
        self.matrix, self.observed, self.noise_std = matrix, data, noise_std
        self.prior_cov = prior_cov
        self.prior_precision = np.linalg.inv(prior_cov)
        self.param_names = tuple(f"p{i}" for i in range(matrix.shape[1]))

    def log_prior(self, theta):
        theta = np.asarray(theta, dtype=float)
        return -0.5 * np.sum((theta @ self.prior_precision) * theta, axis=-1)

    def log_likelihood(self, theta):
        theta = np.asarray(theta, dtype=float)
        resid = (self.observed - theta @ self.matrix.T) / self.noise_std
        return -0.5 * resid**2 - np.log(self.noise_std * np.sqrt(2 * np.pi))

    def initial(self, rng, n):
        return rng.multivariate_normal(np.zeros(self.matrix.shape[1]), self.prior_cov, size=n)


def profile_problem(n: int = 16, h: float = 0.5e-3, depth: float = 0.5e-3, seed: int = 5) -> dict:
    """Operator, data, prior, noise, the true profile and the exact posterior (dense numpy)."""
    op = halfspace_fourier_operator((n,), h, depth, NU, "p", "zz")
    x = (np.arange(n) - n // 2) * h
    truth = 8e3 * np.exp(-x**2 / (2 * 0.8e-3**2)) - 3e3 * np.exp(-(x - 1.5e-3) ** 2 / (2 * 0.5e-3**2))  # Pa
    clean = op.matvec(truth)
    noise = 0.01 * float(np.abs(clean).max())
    data = clean + np.random.default_rng(seed).normal(0.0, noise, n)
    prior = StationaryPrior(variance=5e3**2, correlation_length=1e-3, kind="matern52")
    spectrum = prior.spectrum((n,), h)
    c = np.fft.ifft(spectrum).real  # circulant covariance, first column
    cov = c[(np.arange(n)[:, None] - np.arange(n)[None, :]) % n]
    a = op.matmat(np.eye(n))
    gain = cov @ a.T @ np.linalg.inv(a @ cov @ a.T + noise**2 * np.eye(n))
    mean = gain @ data
    # precision form (no subtraction; cond(cov) is about 700 here): good to ~1e-15, where
    # the subtraction form C - K A C lost digits (1e-11)
    std = np.sqrt(np.diag(np.linalg.inv(np.linalg.inv(cov) + a.T @ a / noise**2)))
    return dict(op=op, matrix=a, data=data, prior=prior, cov=cov, noise=noise, truth=truth, mean=mean, std=std)


def _rel(got, ref) -> float:
    return float(np.linalg.norm(np.asarray(got) - ref) / np.linalg.norm(ref))


def inversion_rows(tols=(1e-2, 1e-4, 1e-6, 1e-8, 1e-10), steps=(300, 1000, 3000, 10000), repeats: int = 3,
                   seed: int = 11) -> list[dict]:
    """One row per (route, setting): time, error of the posterior mean and std vs the exact posterior."""
    prob = profile_problem()
    rng = np.random.default_rng(seed)
    rows = []

    def row(method, setting, seconds, mean, std, note=""):
        rows.append(dict(job="inversion", method=method, setting=setting, time_ms=1e3 * seconds,
                         error=_rel(mean, prob["mean"]), std_error=_rel(std, prob["std"]),
                         truth_error=_rel(mean, prob["truth"]), note=note))

    for method in ("fft", "dense"):
        seconds, post = min_time(lambda m=method: gaussian_posterior(prob["op"], prob["data"], prob["prior"],
                                                                     prob["noise"], method=m), repeats)
        row(method, "exact", seconds, post.mean, post.std, post.note)
    for tol in tols:
        seconds, post = min_time(lambda t=tol: gaussian_posterior(
            prob["op"], prob["data"], prob["prior"], prob["noise"], method="iterative", tol=t,
            rng=np.random.default_rng(seed), n_samples=32), repeats)
        row("iterative", f"tol {tol:.0e}", seconds, post.mean, post.std, post.note)
    model = GaussianProfileModel(prob["matrix"], prob["data"], prob["noise"], prob["cov"])
    for n_steps in steps:  # one run each (the sampler's own settings otherwise)
        t0 = time.perf_counter()
        tree = sample_posterior(model, rng, max_steps=n_steps, check_every=n_steps, n_start=32, info_tol=None)
        seconds = time.perf_counter() - t0
        draws = np.stack([tree["posterior"][name].values.ravel() for name in model.param_names], axis=-1)
        conv = "converged" if tree.attrs.get("converged") else "not converged"
        row("mcmc", f"{n_steps} steps", seconds, draws.mean(axis=0), draws.std(axis=0),
            f"{conv}; tau {tree.attrs['tau_max']:.0f} steps; "
            f"{int(tree.attrs.get('n_walkers'))} walkers x 4 ensembles")
        rows[-1].update(tau=float(tree.attrs["tau_max"]), kept=int(tree.attrs["n_kept"]))
    return rows


# -- page ---------------------------------------------------------------------------------------
def plot(forward: list[dict], inversion: list[dict], path: Path) -> None:
    """Two log-log panels, time (ms) against relative error, one curve per method."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 5), layout="constrained")
    ax_f, ax_i = fig.subplots(1, 2)
    for method in FORWARD_METHODS:
        rs = [r for r in forward if r["method"] == method]
        if not rs:
            continue
        t = [r["time_ms"] for r in rs]
        ax_f.loglog(t, [r["error"] for r in rs], "o-", color=COLORS[method], label=f"{method}: true error")
        ax_f.loglog(t, [r["estimate"] for r in rs], "x--", color=COLORS[method], alpha=0.7,
                    label=f"{method}: its error_estimate")
        for r in rs:
            ax_f.annotate(f"a/{r['per_a']}", (r["time_ms"], r["error"]), fontsize=7, textcoords="offset points",
                          xytext=(3, 3))
    ax_f.set(xlabel="time per call (ms)", ylabel="relative error (max over points, / peak stress)",
             title=f"Forward: sliding Hertz contact, a = {A * 1e3:g} mm, mu = {MU}, depth a/2")
    ax_f.legend(fontsize=7)
    ax_f.grid(True, which="both", alpha=0.3)
    for method in INVERSION_METHODS:
        rs = [r for r in inversion if r["method"] == method]
        if not rs:
            continue
        floor = [max(r["error"], 1e-16) for r in rs]
        ax_i.loglog([r["time_ms"] for r in rs], floor, "o-", color=COLORS[method], label=f"{method}: mean")
        if method == "mcmc":  # its std is the check on the sampler's spread
            ax_i.loglog([r["time_ms"] for r in rs], [r["std_error"] for r in rs], "x--", color=COLORS[method],
                        alpha=0.7, label="mcmc: pointwise std")
        for i, r in enumerate(rs):
            if r["setting"] != "exact":  # labels alternate above and below the curve
                ax_i.annotate(r["setting"], (r["time_ms"], max(r["error"], 1e-16)), fontsize=7, ha="center",
                              textcoords="offset points", xytext=(0, 5 if i % 2 == 0 else -11))
    ax_i.set_xlim(right=3 * max(r["time_ms"] for r in inversion))
    ax_i.set(xlabel="time per solve (ms)", ylabel="relative L2 error vs the exact posterior",
             title="Inversion: 16-node pressure profile vs its exact posterior")
    ax_i.legend(fontsize=8)
    ax_i.grid(True, which="both", alpha=0.3)
    fig.savefig(path, dpi=120)


def _forward_table(rows: list[dict]) -> list[str]:
    out = ["| method | spacing | grid | time (ms) | true error | error_estimate | of which method | of which sampling "
           "| estimate / true |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        ratio = r["estimate"] / r["error"] if r["error"] > 0 else float("inf")
        out.append(f"| {r['method']} | a/{r['per_a']} | {r['grid']}^2 | {r['time_ms']:.3g} | {r['error']:.2e} | "
                   f"{r['estimate']:.2e} | {r['method_estimate']:.1e} | {r['sampling_estimate']:.1e} | {ratio:.2g} |")
    return out


def _inversion_table(rows: list[dict]) -> list[str]:
    out = ["| route | setting | time (ms) | error of mean | error of std | mean vs true profile | note |",
           "|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['method']} | {r['setting']} | {r['time_ms']:.3g} | {r['error']:.2e} | {r['std_error']:.2e} | "
                   f"{r['truth_error']:.2e} | {r['note']} |")
    return out


def _best(rows, method, key="error"):
    rs = [r for r in rows if r["method"] == method]
    return min(rs, key=lambda r: r[key]) if rs else None


def write_page(forward: list[dict], inversion: list[dict], out_dir: Path, command: str, load: str) -> Path:
    """docs/accuracy.md (and the PNG beside it)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    png = out_dir / "accuracy.png"
    plot(forward, inversion, png)
    covers = sorted({r["covers"] for r in forward if r["covers"]})
    under = [r for r in forward if r["estimate"] < r["error"]]
    lines = [
        "# Accuracy against time: which method for which need",
        "",
        "Written by `benchmarks/bench_tradeoff.py` from one run; every error below is a TRUE error against",
        "an answer computed apart from the method. Times are the minimum over repeats, one FFT thread.",
        "",
        f"- Command: `{command}`",
        f"- Machine: {platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}; "
        f"load at start (`uptime`): {load}",
        f"- Date (UTC): {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M}",
        "",
        "![time against true error](accuracy.png)",
        "",
        "## Forward: a sliding Hertz contact",
        "",
        f"Contact radius a = {A * 1e3:g} mm, friction mu = {MU} (sliding: qx = mu p), nu = {NU}, all six stress",
        "components at depth a/2, at 34 sensors every a/4 on the lines y = 0 and y = a/2 with |x| <= 2a (the",
        "same points on every grid: nodes of every grid used). The load",
        "is the contact itself, `HertzContact.load(friction=0.5, condition=\"sliding\", spacing=h, half_width=w)`:",
        "the solver samples it on the grid, and also on grids of spacing 2h and 4h to bound the sampling",
        "error (the times include those solves). Each method is forced (`method=...`).",
        "`closed_form` and `dcfft` run on a grid covering [-2a, 2a]^2 (the traction is zero outside it);",
        f"`spectral` runs on a periodic box of side {BOX} a, so the contact repeats every {BOX} mm: large",
        "enough that the images stay below the sampling error down to a spacing of about a/16, below which",
        "they set the method's floor. True error: max |sigma - sigma_H| / max |sigma_H| over the points",
        "and components, sigma_H from Hamilton's closed form (`benchmarks/hamilton_reference.py`).",
        "`error_estimate` is what the result reports about itself (same scale: relative to the peak), the",
        "sum of the method's own estimate and the sampling estimate (`attrs[\"method_error_estimate\"]`,",
        "`attrs[\"sampling_error_estimate\"]`).",
        "",
        *_forward_table(forward),
        "",
    ]
    if covers:
        lines += [f"What the estimates say they cover (`attrs[\"error_covers\"]`): {'; '.join(covers)}.", ""]
    if under:
        worst = max(under, key=lambda r: r["error"] / max(r["estimate"], 1e-300))
        lines += [f"In {len(under)} of {len(forward)} rows the reported estimate is below the true error (worst: "
                  f"{worst['method']} at a/{worst['per_a']}, estimate {worst['estimate']:.1e} against "
                  f"{worst['error']:.1e}).", ""]
    else:
        ratios = [r["estimate"] / r["error"] for r in forward if r["error"] > 0]
        lines += [f"Every reported estimate is at or above the true error, by {min(ratios):.2g}x to "
                  f"{max(ratios):.2g}x. Almost all of the error is the sampling of the contact (its square-root "
                  "edge) on the grid: the methods' own estimates are far smaller, except spectral's, which counts "
                  "the periodic images.", ""]
    lines += [
        "## Inversion: one pressure profile, four routes",
        "",
        "A plane-strain pressure profile on 16 periodic nodes 0.5 mm apart, sigma_zz measured at 0.5 mm",
        "depth under every node, noise 1 % of the peak signal, Matern-5/2 prior (sd 5 kPa, correlation",
        "length 1 mm). Error of mean (of std): relative L2 distance of the route's posterior mean (pointwise",
        "std) from the exact posterior, computed in the script with dense numpy algebra independently of",
        "`tactilab.inversion` (mean: C A^T (A C A^T + s^2 I)^-1 d; std: the diagonal of (C^-1 + A^T A / s^2)^-1).",
        "For MCMC the mean and std are those of the draws (4 ensembles of 64 walkers, first 25 % of every",
        "chain dropped); 'tau' is emcee's integrated autocorrelation time of the kept chains (the largest",
        "over parameters and ensembles; it is underestimated when the kept chain is shorter than about",
        "50 tau, so the longest run's value is the one to trust). 'mean vs true profile'",
        "is the distance from the pressure that made the data: the inference error every route shares.",
        "",
        *_inversion_table(inversion),
        "",
        "## Which method for which need",
        "",
    ]
    lines += _advice(forward, inversion)
    md = out_dir / "accuracy.md"
    md.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return md


def _advice(forward: list[dict], inversion: list[dict]) -> list[str]:
    """The closing recommendations, with the numbers of this run."""
    def at(method, m):
        return next((r for r in forward if r["method"] == method and r["per_a"] == m), None)

    fine, coarse = max(r["per_a"] for r in forward), min(r["per_a"] for r in forward)
    d, s, c, c0 = at("dcfft", fine), at("spectral", fine), at("closed_form", fine), at("closed_form", coarse)
    by = {r["method"]: r for r in inversion if r["setting"] == "exact"}
    it = _best(inversion, "iterative")
    lines = ["Forward (the stress under a contact):", ""]
    if d and s and c and c0:
        lines += [
            f"- An isolated contact on a grid: `dcfft`. At a/{fine} it took {d['time_ms']:.3g} ms for a true error of "
            f"{d['error']:.1e} (estimate {d['estimate']:.1e}). The error is the grid's sampling of the contact's "
            "square-root edge, not the method: give the contact itself (`HertzContact.load(...)`) and a `tol`, and "
            "`method=\"auto\"` refines the grid until the estimate meets it.",
            f"- Few sensors and a small loaded patch: `closed_form`, exact sums over the loaded nodes "
            f"({c0['time_ms']:.3g} ms at a/{coarse}); its cost is loaded nodes x sensors, so it falls behind `dcfft` "
            f"as either grows ({c['time_ms']:.3g} ms against {d['time_ms']:.3g} ms at a/{fine} for "
            f"{len(sensor_points())} sensors).",
            f"- A periodic load (gratings, textures): `spectral`, exact for the nodal values of a periodic load. "
            f"For an isolated contact it pays twice: a box many contact widths wide (here {BOX} a, "
            f"{s['grid']}^2 nodes at a/{fine}, {s['time_ms']:.3g} ms) and the periodic images, which set a floor "
            f"(here {s['error']:.1e}, reached from a/{_floor_start(forward)}); its estimate "
            f"({s['estimate']:.1e}) covers them.",
        ]
    lines += ["", "Inversion (the posterior of a linear-Gaussian problem):", ""]
    if "fft" in by:
        lines.append(f"- A periodic grid with a sensor under every node (a `FourierDiagonal` operator): the `fft` "
                     f"path, exact and the fastest ({by['fft']['time_ms']:.3g} ms, error {by['fft']['error']:.1e}).")
    if "dense" in by:
        lines.append(f"- Any other operator up to a few thousand unknowns: `dense`, exact "
                     f"({by['dense']['time_ms']:.3g} ms here, error {by['dense']['error']:.1e}); its cost grows as n^3.")
    if it:
        lines.append(f"- Large matrix-free operators: `iterative`. Its mean reached {it['error']:.1e} at "
                     f"{it['setting']} ({it['time_ms']:.3g} ms); its pointwise std is Monte Carlo (error "
                     f"{it['std_error']:.1e} here), so ask for more samples when the std matters.")
    runs = [r for r in inversion if r["method"] == "mcmc"]
    if runs:
        mc = runs[-1]  # the longest run
        lines.append(f"- MCMC (`sample_posterior`) only for what the Gaussian routes cannot do: non-linear or "
                     f"non-Gaussian models, scene parameters. On this 16-parameter linear problem the integrated "
                     f"autocorrelation time is about {mc['tau']:.0f} steps; after {mc['setting']} "
                     f"({mc['time_ms'] / 1e3:.3g} s) the mean was {mc['error']:.1e} and the pointwise std "
                     f"{mc['std_error']:.1e} off the exact ones, Monte Carlo error of one run (so it does not "
                     "fall steadily from setting to setting). The sampler calls a run converged only when the "
                     "kept chain (after "
                     f"its 25 % burn-in) is 50 tau long, here about {math.ceil(50 * mc['tau'] / 0.75):,} steps. "
                     "One run per setting, so its times are single measurements.")
    return lines


def _floor_start(forward: list[dict]) -> int:
    """The coarsest spacing (a/m) from which spectral's error stops falling by more than 25 %."""
    rs = [r for r in forward if r["method"] == "spectral"]
    for prev, cur in zip(rs, rs[1:]):
        if cur["error"] > 0.75 * prev["error"]:
            return prev["per_a"]
    return rs[-1]["per_a"] if rs else 0


def _uptime() -> str:
    try:
        return subprocess.run(["uptime"], capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "load average %.2f %.2f %.2f" % os.getloadavg()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two grids, few settings (about 20 s)")
    parser.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / "docs"),
                        help="folder for accuracy.md and accuracy.png (default: docs/)")
    args = parser.parse_args(argv)
    load = _uptime()
    t0 = time.perf_counter()
    if args.quick:
        forward = forward_rows(per_a=(4, 8), repeats=2)
        inversion = inversion_rows(tols=(1e-3, 1e-8), steps=(1000,), repeats=2)
    else:
        forward = forward_rows()
        inversion = inversion_rows()
    command = "python benchmarks/bench_tradeoff.py" + (" --quick" if args.quick else "")
    md = write_page(forward, inversion, Path(args.out), command, load)
    for line in _forward_table(forward) + [""] + _inversion_table(inversion):
        print(line)
    print(f"\nwrote {md} and {md.with_suffix('.png')} in {time.perf_counter() - t0:.0f} s; load at start: {load}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
