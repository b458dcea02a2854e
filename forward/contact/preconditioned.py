"""Normal contact by preconditioned conjugate gradients on a working set (the default method).

Same problem as :mod:`.normal` (``p >= 0``, ``g = g0 + uz(p) - delta >= 0``, ``p g = 0``, the force
or the approach given). Polonsky and Keer's iteration needs a number of iterations that grows
like the square root of the grid's width, because the compliance's spectrum ``2 / (E* |k|)``
spans the ratio of the grid's largest and smallest wavenumbers. Here each iteration is
preconditioned by the periodic surface stiffness ``E* |k| / 2`` (the exact inverse of the
compliance on a fully touching periodic grid; on periodic 2-D grids by default its two-level
approximation, :meth:`ContactCompliance.preconditioner`), restricted to the working set, which
cuts the iterations five- to seven-fold on rough surfaces (30 instead of 206 at 512^2, 10 %
contact), in the spirit of Vollebregt's bound-constrained CG (J. Optim. Theory Appl. 162, 2014).

One iteration:

1. the gap ``g`` (force control: minus its mean over the contact set, which sets ``delta``);
2. the working set ``S``: nodes in contact and nodes that penetrate (``g < 0``), which enter;
3. the residual ``r = g`` on ``S``; the preconditioned residual ``z = K r`` on ``S`` (force
   control: minus its mean on ``S``, so that the step keeps the force);
4. the direction ``t = z + beta t_old`` on ``S``, with Polak-Ribiere's
   ``beta = max(0, <r, z - z_old> / <r_old, z_old>)`` (PR+), which restarts (``beta = 0``) by
   itself when the working set's change spoils the conjugacy;
5. the exact step ``tau = <r, t> / <A t, t>``; ``p = max(p - tau t, 0)``, rescaled to the force.

Products: one compliance product ``A t`` and one preconditioner product ``K r`` per iteration
(the preconditioner is an FFT pair of the unpadded grid, a quarter of a padded product for an
isolated contact, or on a periodic grid the two-level stiffness: two passes and a pair of 1/64
of the nodes). ``uz = A p`` is updated as ``uz - tau A t``; a pressure clipped to 0 adds its
correction by direct summation of the influence coefficients when few nodes are clipped (up to
``ContactCompliance.direct_limit``, about 8 on a periodic grid and 36 on a padded 256^2 one; beside
float32 corrections :data:`POINTS_SHARE` times that, from float32 coefficients, :mod:`.point_loads`),
by a float32 FFT pair when more are (:mod:`.single_correction`, while the accumulated bound of its
round-off stays below :data:`SINGLE_SHARE` of the residual; added by the next gap pass), and ``uz``
is recomputed by a float64 FFT pair otherwise, every 32 iterations, and before convergence is
declared. On 2-D grids the direction's product ``A t`` itself runs as a float32 FFT pair
(:meth:`.SingleCorrection.transform_direction`, ``<A t, t>`` by Parseval in its multiplier's pass)
while its round-off, added to the same bound, keeps it below the same share of the residual (where
the drift blocks it, ``uz`` is recomputed first; float64 products for a nearly full start); the
residual, the direction and the preconditioned residuals are then float32 arrays, and the exact
stiffness a float32 pair: the same iterations, the loop per iteration within 2x of the FFT floor
(docs/contact.md, Table a4).
Clipping of many nodes happens in most iterations until the contact set settles (self-affine
surface, 10 % contact: hundreds to thousands of nodes for the first two thirds of the iterations,
a few in the tail), so an iteration costs between two and three FFT pairs of the grid with the
exact stiffness (between one and two with the two-level one), where Polonsky-Keer's costs about
two: the iterations saved pay for it twice over.

Between the products an iteration makes about 30 elementwise passes over the grid in NumPy; they
run as six fused loops compiled by numba (:mod:`.kernels` and :mod:`.step_kernels`, through
:mod:`tactilab.core.jit`), or as the NumPy twin where numba is absent or ``TACTILAB_JIT=0``: the same
iterates either way, to round-off (docs/contact.md, Table a4, has the measured share of each). Work
arrays come from :mod:`.work_arrays` (kept between solves of small grids).
"""

from __future__ import annotations

import numpy as np

from tactilab.core import jit

from . import kernels, single_correction, step_kernels
from .work_arrays import work_arrays
from .normal import REFRESH, NormalResult

#: start's contact fraction above which "auto" takes the exact stiffness (at 99 % contact it needs 12
#: to 14 iterations against the two-level one's 16 to 17, and a full contact comes out exact)
NEARLY_FULL = 0.95
#: float32 corrections are used while their accumulated error bound stays below this share of the residual
SINGLE_SHARE = 0.01
#: the direct summation's node limit beside float32 corrections, in ContactCompliance.direct_limit's (compiled
#: float32 summation: 24 to 30 nodes on periodic grids, about 100 on a padded 256^2 one)
POINTS_SHARE = 3


def preconditioned_cg(compliance, g0: np.ndarray, *, total: float | None, approach: float | None, tol: float,
                      max_iter: int, p0: np.ndarray, extra_gap: np.ndarray | None = None,
                      preconditioner: str = "auto", single_corrections: bool = True,
                      single_products: bool = True) -> NormalResult:
    """Solve the frictionless normal contact on one grid; the arguments of :func:`.normal.polonsky_keer`,
    ``preconditioner``, the kind of :meth:`ContactCompliance.preconditioner` (``"auto"`` takes the
    exact stiffness when the start touches more than :data:`NEARLY_FULL` of the nodes), and
    ``single_corrections``: after a step that clips many nodes, add their correction by a float32 FFT
    pair (:mod:`.single_correction`; a few nodes by direct summation from float32 coefficients) instead of
    recomputing ``uz`` in float64 (False: recompute; a few nodes from float64 coefficients), and
    ``single_products``: on a 2-D grid, compute the direction's product ``A t`` by a float32 FFT pair while
    the accumulated bound of its round-off stays below :data:`SINGLE_SHARE` of the residual, with the
    residual, the direction and the preconditioned residuals in float32 and the exact stiffness by a
    float32 pair (False: all in float64)."""
    g0 = np.ascontiguousarray(g0 if extra_gap is None else g0 + extra_gap, dtype=float)  # the kernels loop flat
    scale = float(g0.max() - g0.min()) or float(np.abs(g0).max()) or 1.0
    target = tol * scale
    force = total is not None
    p = np.array(p0, dtype=float, order="C")
    if force:
        s = p.sum()
        p = p * (total / s) if s > 0 else np.full(p.shape, total / p.size)
    if preconditioner == "auto" and np.count_nonzero(p) > NEARLY_FULL * p.size:
        preconditioner = "fft"  # the exact stiffness inverts a full periodic contact: exact in one step,
        single_products = False  # given a float64 product (a float32 one took 4 steps instead of 1 or 2)
    A, K = compliance.normal, compliance.preconditioner(preconditioner)
    # work arrays, reused: every pass over the grid costs about as much as a tenth of an FFT pair,
    # and a fresh grid-sized array about as much again (page faults)
    g = np.empty_like(p)  # returned: fresh
    r, tmp, t, At, u, z, z_other, inside, S = work_arrays(p.shape)
    u = A(p, out=u)
    products, exact = 1, True
    G_old, residual, delta = 0.0, np.inf, approach
    # the elementwise passes: fused compiled kernels or their NumPy twins (one choice per solve)
    compiled = jit.enabled()
    # clipped nodes up to which the displacement is corrected by direct summation, not an FFT pair
    limit = getattr(compliance, "direct_limit", 0)
    # single corrections record every clipped node (16 bytes a node), direct summations the first few
    mixer = single_correction.kept(compliance) if single_corrections or single_products else None
    single = mixer if single_corrections else None
    # mixed-precision direction products (float32 FFT pairs into mixer's kept arrays): 2-D grids
    mixed = single_products and mixer is not None and mixer.dense_2d
    if mixed:  # the residual, the direction and the preconditioned residuals in float32: the float32
        # product's input as they are, a third less memory traffic in the passes that read them
        # (docs/contact.md, Cost); the residual pass then leaves the float64 residual in g
        r, t, z, z_other = work_arrays(p.shape, np.float32, 4, 0)
        if K == compliance.stiffness:  # the exact stiffness (isolated grids): by a float32 pair too
            K = mixer.stiffness
    z_pair = (z, z_other)  # z and z_old alternate
    z_old = np.zeros_like(z)
    # a few clipped nodes: float32 direct summation beside the float32 corrections on 2-D grids (compiled:
    # 0.015 to 0.03 floors a node against the correction's 0.55 to 0.7; the float64 summation's 0.07 to
    # 0.12 set limit); its coefficients made on first use
    direct32 = single is not None and single.dense_2d
    if direct32:
        limit *= POINTS_SHARE
    size = p.size if single is not None else max(limit, 1)
    nodes, values = np.empty(size, dtype=np.int64), np.empty(size)
    factor, it = 1.0, 0  # factor: the force rescaling of p and u, applied by the next gap pass
    pending = None  # a float32 clip correction (mixer's kept array), added to u by the next gap pass
    last_step = 0.0  # the last float32 product's share of drift, m
    drift = 0.0  # bound on |uz - A p| from the float32 corrections since the last float64 product, m
    while True:
        n_in, sum_in, peak = kernels.gap(g0, u, p, g, inside, factor, compiled, pending)
        if pending is not None:  # the correction's bound a posteriori, from its max (as the products')
            drift += single.product_bound(peak) - prior
        factor, pending = 1.0, None
        if force:
            delta = sum_in / n_in if n_in else float(g.min())
        # the working set S (in contact, or penetrating: entering), r = g on S; max |r| is |g| in
        # contact and the penetration elsewhere
        residual, n_set = kernels.residual(g, delta, p, inside, S, r, compiled)
        if residual <= target or it >= max_iter:
            if exact or it >= max_iter:
                break
            u, exact, drift = A(p, out=u), True, 0.0  # confirm on the exact displacement
            products += 1
            continue
        z = K(r, out=z_pair[it % 2])
        G, rz_old = kernels.project(z, S, n_set, r, z_old, force, compiled)
        # Polak-Ribiere, clipped at 0 (PR+): restarts by itself when the working set's change spoils
        # the conjugacy; restarting at every entering node (Fletcher-Reeves) took 51 iterations
        # instead of 30 at 512^2 and 89 instead of 40 at 1024^2 (periodic self-affine, 10 % contact)
        beta = max(0.0, (G - rz_old) / G_old) if G_old > 0 else 0.0
        # mixed: a float32 product while the round-off it adds to uz (predicted from the last one's) keeps
        # the drift's bound below SINGLE_SHARE of the residual: far from convergence (a floor on the
        # residual, 1e-4 of the scale, as well left a third more float64 products: docs/contact.md, Cost)
        cheap_product = mixed and drift + last_step <= SINGLE_SHARE * residual
        if mixed and not cheap_product and drift and last_step <= SINGLE_SHARE * residual:
            # the drift, not the product, is in the way: uz recomputed now and a float32 product, rather
            # than a float64 product and uz recomputed after it (two float64 pairs where one does); this
            # iteration's gap had the drift, as it would have had with a float64 product
            u, exact, drift = A(p, out=u), True, 0.0
            products += 1
            cheap_product = True
        rt = kernels.direction(t, z, S, beta, r, compiled)  # nodes that left S leave the direction
        z_old, G_old = z, G
        if cheap_product:  # float32, mixer's kept array; <A t, t> by Parseval in the same transforms
            step_product, denom = mixer.transform_direction(t, compiled)
            products += 1
        else:
            step_product = At = A(t, out=At)
            products += 2
            denom = step_kernels.dot(At, t, compiled)
        tau = rt / denom if denom > 0 else 0.0
        # p -= tau t, clipped at 0; u -= tau A t in the same pass (wasted where u is recomputed below), and
        # max |A t|, the float32 product's error bound
        m, sum_p, peak = step_kernels.descend(p, t, tau, nodes, values, tmp, force, u, step_product, compiled)
        it += 1
        if cheap_product:
            last_step = abs(tau) * mixer.product_bound(peak)
            drift += last_step
        cheap = m > limit and single is not None and \
            drift + single.bound(values[:m]) <= SINGLE_SHARE * residual
        # uz recomputed by a float64 FFT pair
        if it % REFRESH == 0 or (m > limit and not cheap) or drift > SINGLE_SHARE * residual:
            _rescale(p, total, sum_p)
            u, exact, drift = A(p, out=u), True, 0.0
            products += 1
        else:  # u = A p updated in place, the pressure added to bring each clipped node back to 0 with it
            if m > limit:  # many: by a float32 FFT pair, on 2-D grids added by the next gap pass
                prior = single.bound(values[:m])  # a priori (Czz sum(c), the most |A c| can reach)
                drift += prior
                if single.dense_2d:
                    pending = single.correction(nodes[:m], values[:m])
                else:
                    single.add(u, nodes[:m], values[:m])
            elif m and direct32:  # a few: by direct summation, float32 coefficients
                drift += single.points.bound(values[:m])
                single.points.add(u, nodes[:m], values[:m])
            elif m:  # a few: by direct summation
                compliance.add_normal_point_loads(u, nodes[:m], values[:m])
            factor = total / sum_p if force else 1.0
            exact = False
    if r.dtype == np.float32:  # g holds the residual: the gap again, as the gap and residual passes make it
        np.add(g0, u, out=g)
        g -= delta
    return NormalResult(p, float(delta), g, it, residual <= target, residual, products)


def _rescale(p: np.ndarray, total: float | None, sum_p: float) -> None:
    """Scale ``p`` (sum ``sum_p``, Pa) in place to the force ``total`` (None: approach control, no scaling)."""
    factor = total / sum_p if total is not None else 1.0
    if factor != 1.0:
        p *= factor
