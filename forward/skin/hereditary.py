"""Hereditary integrals of a Prony kernel by recursive convolution: O(terms) work per time step.

For a kernel ``K(t) = K_inf + sum_j K_j exp(-t / theta_j)`` (a relaxation modulus or a creep
compliance, :meth:`Prony.kernel`) and an input history ``a(t)`` (a field of any shape per time),

    c(t) = integral from 0- to t of K(t - s) da(s),

with ``a = 0`` before the first time ``t_0`` (so ``a(t_0)`` is applied as a step at ``t_0``) and
``a`` linear in time between the given samples. Then ``c(t_n) = K_inf a_n + sum_j K_j h_j(t_n)``
with one internal variable per term, ``h_j(t) = integral exp(-(t - s) / theta_j) da(s)``, which
advances exactly over a step ``dt`` of linear ``a``::

    h_j <- exp(-dt / theta_j) h_j + g_j(dt) (a_n - a_{n-1}),   g_j(dt) = theta_j (1 - exp(-dt / theta_j)) / dt

(``g_j -> 1`` as ``dt -> 0``; computed with ``expm1``). So ``c_n = gain(dt) a_n + memory`` where
``gain(dt) = K_inf + sum_j K_j g_j(dt)`` and ``memory = sum_j K_j (exp(-dt / theta_j) h_j - g_j a_{n-1})``
depends on the past only: a time-stepped solver (:mod:`.viscoelastic_contact`) solves for ``a_n``
with that split. The scheme is exact for piecewise linear inputs (a step, a ramp, a held load).
"""

from __future__ import annotations

import numpy as np


def _gains(dt: float, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(exp(-dt / theta), theta (1 - exp(-dt / theta)) / dt)`` per term; ``(1, 1)`` at ``dt = 0``."""
    x = dt / theta
    decay = np.exp(-x)
    with np.errstate(divide="ignore", invalid="ignore"):
        g = np.where(x > 0, -np.expm1(-x) / np.where(x > 0, x, 1.0), 1.0)
    return decay, g


class HereditaryIntegral:
    """State of one hereditary integral, advanced step by step (see the module docstring).

    Parameters
    ----------
    kernel : (float, ndarray, ndarray)
        ``(K_inf, K_j, theta_j)`` as :meth:`Prony.kernel` returns it; ``theta_j`` in s.
    shape : tuple of int
        Shape of the input field at one time.
    """

    def __init__(self, kernel, shape=()):
        self.k_inf, self.k_j, self.theta = float(kernel[0]), np.asarray(kernel[1], float), np.asarray(kernel[2], float)
        self.h = np.zeros((len(self.theta),) + tuple(shape))
        self.previous = np.zeros(tuple(shape))  # a at the last time (0 before the first)
        self.started = False

    def split(self, dt: float) -> tuple[float, np.ndarray]:
        """``(gain, memory)`` with ``c_n = gain a_n + memory`` for the next sample ``dt`` s later
        (the first sample's ``dt`` is ignored: it is a step, ``gain = K(0)``)."""
        if not self.started:
            return self.k_inf + float(self.k_j.sum()), np.zeros_like(self.previous)
        decay, g = _gains(dt, self.theta)
        gain = self.k_inf + float(np.dot(self.k_j, g))
        memory = -float(np.dot(self.k_j, g)) * self.previous
        for k, d, h in zip(self.k_j, decay, self.h):  # a loop over the few terms: no BLAS call on a field
            memory += (k * d) * h
        return gain, memory

    def advance(self, dt: float, a) -> None:
        """Take the sample ``a`` (the input at ``dt`` s after the last sample) into the state."""
        a = np.asarray(a, dtype=float)
        shape = (-1,) + (1,) * a.ndim
        if not self.started:
            self.h[...] = a  # a step from 0 at the first time
            self.started = True
        else:
            decay, g = _gains(dt, self.theta)
            self.h *= decay.reshape(shape)
            self.h += g.reshape(shape) * (a - self.previous)
        self.previous = a.copy()

    def value(self) -> np.ndarray:
        """``c`` at the last sample."""
        out = self.k_inf * self.previous
        for k, h in zip(self.k_j, self.h):
            out += k * h
        return out


def check_times(times, name: str = "times") -> np.ndarray:
    """Sample times in s: 1-D, finite, >= 0, strictly increasing, at least one."""
    t = np.atleast_1d(np.asarray(times, dtype=float))
    if t.ndim != 1 or t.size == 0:
        raise ValueError(f"{name}: expected a 1-D sequence of times in s, got shape {np.shape(times)}")
    if not np.all(np.isfinite(t)) or (t < 0).any():
        raise ValueError(f"{name}: times must be finite and >= 0 s (t = 0 is the start of the load history), "
                         f"got {float(t[~np.isfinite(t) | (t < 0)][0])!r}")
    if (np.diff(t) <= 0).any():
        i = int(np.argmax(np.diff(t) <= 0))
        raise ValueError(f"{name}: times must increase strictly, got {float(t[i])!r} then {float(t[i + 1])!r}; sort them and "
                         "drop repeats")
    return t


def convolve(kernel, times, values) -> np.ndarray:
    """``c(t_n)`` for every sample: the hereditary integral of ``values`` (shape ``(n_times, ...)``)."""
    times = np.asarray(times, dtype=float)
    values = np.asarray(values, dtype=float)
    state = HereditaryIntegral(kernel, values.shape[1:])
    out = np.empty_like(values)
    previous = times[0]
    for n, (t, a) in enumerate(zip(times, values)):
        state.advance(t - previous, a)
        out[n] = state.value()
        previous = t
    return out


def convolution_matrix(kernel, times) -> np.ndarray:
    """The lower-triangular matrix ``T`` with ``c = T @ a`` over the samples (for the operators' adjoints)."""
    times = np.asarray(times, dtype=float)
    return convolve(kernel, times, np.eye(len(times)))
