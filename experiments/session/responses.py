"""Response sources: a terminal for real subjects and a simulated observer for dry runs.

Both implement :class:`ResponseSource`: ``arm(plan, onset_ns)`` is called just before the
stimulus is driven (the response clock starts at its onset, ``time.monotonic_ns``), and
``collect(plan)`` returns the :class:`Response` after the stimulus has played.
"""

from __future__ import annotations

import abc
import math
import os
import select
import sys
import threading
import time
from dataclasses import dataclass
from typing import Callable, TextIO

import numpy as np
from scipy.special import ndtri

from tactilab.core import rules
from tactilab.data_schemas.experiment import Protocol, Stimulus
from tactilab.forward.tractors import sliding_sinusoid_strain

from ..procedures import TrialPlan

_QUIT_KEYS = ("q", "\x03", "\x1b")  # q, Ctrl-C (raw), Esc


@dataclass(frozen=True)
class Response:
    """A response label, its time from stimulus onset (s) and its monotonic time stamp (ns)."""

    label: str
    rt_s: float
    monotonic_ns: int


class ResponseSource(abc.ABC):
    """Where responses come from; ``name`` is recorded with the session."""

    name = "abstract"

    @property
    def config(self) -> dict:
        """Settings recorded with the session and checked on resume (none by default)."""
        return {}

    def arm(self, plan: TrialPlan, onset_ns: int) -> None:
        """Start listening: called right before the first stimulus of ``plan`` is driven."""
        self._onset_ns = onset_ns

    def on_screen(self, stream: TextIO) -> bool:
        """True when what is written to ``stream`` shows on the subject's screen (the runner
        then keeps the running estimate off it). None by default: no subject is watching."""
        return False

    @abc.abstractmethod
    def collect(self, plan: TrialPlan) -> Response:
        """Return the response to ``plan`` (blocks for a real subject)."""

    def close(self) -> None:
        """Release the terminal or other resources."""


class TerminalResponses(ResponseSource):
    """Single keypresses on a terminal, no Enter, timed from stimulus onset.

    The terminal is put in cbreak mode (``tty.setcbreak``: keys arrive one by one, unechoed;
    Ctrl-C still raises KeyboardInterrupt so the safety layer zeroes the display). Keys typed
    before the onset are discarded; keys during and after the stimulus are time-stamped as
    they arrive by a reader thread, so the response time does not include playback time.
    ``q`` or Esc ends the session (KeyboardInterrupt). Unknown keys ring the bell and are
    ignored.

    Parameters
    ----------
    protocol : Protocol
        Its task gives the prompt and the key -> response mapping.
    stdin, stdout : file objects, optional
        A terminal (default ``sys.stdin``, ``sys.stdout``).
    """

    name = "terminal"

    def __init__(self, protocol: Protocol, stdin: TextIO | None = None, stdout: TextIO | None = None):
        import termios
        import tty

        self.task = protocol.task
        self.stdin = stdin if stdin is not None else sys.stdin
        self.stdout = stdout if stdout is not None else sys.stdout
        try:
            self.fd = self.stdin.fileno()
        except (OSError, ValueError):  # e.g. a pseudo-file under a test runner
            self.fd = -1
        if self.fd < 0 or not os.isatty(self.fd):
            raise OSError(
                "--responses terminal: standard input is not a terminal; run in an interactive "
                "terminal or use --responses simulated"
            )
        self._termios = termios
        self._saved = termios.tcgetattr(self.fd)
        tty.setcbreak(self.fd)
        self._keys: list[tuple[str, int]] = []
        self._lock = threading.Condition()
        self._listening = threading.Event()
        self._closed = False
        self._thread = threading.Thread(target=self._reader, daemon=True)
        self._thread.start()

    def _reader(self) -> None:
        while not self._closed:
            ready, _, _ = select.select([self.fd], [], [], 0.05)
            if not ready:
                continue
            stamp = time.monotonic_ns()
            char = os.read(self.fd, 1).decode("utf-8", "replace")
            if self._listening.is_set():
                with self._lock:
                    self._keys.append((char, stamp))
                    self._lock.notify_all()

    def prompt_text(self) -> str:
        """The on-screen question with its keys."""
        question = self.task.prompt or {
            "2ifc": "Which interval held the stimulus?",
            "2afc": "Which one was it?",
            "yes_no": "Did you feel a stimulus?",
            "same_different": "Were the two stimuli the same or different?",
            "magnitude_estimation": "How strong was it?",
        }[self.task.kind]
        keys = "  ".join(f"[{k}] {label}" for k, label in self.task.key_map.items())
        return f"{question}  {keys}  ([q] quits)"

    def on_screen(self, stream: TextIO) -> bool:
        """True when ``stream`` writes to the subject's terminal (the same terminal device as
        the prompt's stream or the keys' input)."""
        try:
            device = os.fstat(stream.fileno())
        except (OSError, ValueError, AttributeError):  # a pseudo-file: not a screen at all
            return False
        if not os.isatty(stream.fileno()):
            return False
        mine = [self.fd]
        try:
            mine.append(self.stdout.fileno())
        except (OSError, ValueError, AttributeError):
            pass
        return any((os.fstat(fd).st_rdev, os.fstat(fd).st_dev) == (device.st_rdev, device.st_dev) for fd in mine)

    def arm(self, plan, onset_ns):
        super().arm(plan, onset_ns)
        self._termios.tcflush(self.fd, self._termios.TCIFLUSH)  # drop anticipatory keys
        with self._lock:
            self._keys.clear()
        self._listening.set()

    def collect(self, plan):
        self.stdout.write(self.prompt_text() + "\n")
        self.stdout.flush()
        key_map = self.task.key_map
        try:
            while True:
                with self._lock:
                    while not self._keys:
                        self._lock.wait(0.1)
                    char, stamp = self._keys.pop(0)
                if char in _QUIT_KEYS:
                    raise KeyboardInterrupt("the subject pressed quit")
                if char in key_map:
                    return Response(key_map[char], max(stamp - self._onset_ns, 0) / 1e9, stamp)
                self.stdout.write("\a")
                self.stdout.flush()
        finally:
            self._listening.clear()

    def close(self):
        self._closed = True
        self._thread.join(timeout=1.0)
        self._termios.tcsetattr(self.fd, self._termios.TCSADRAIN, self._saved)


def receptor_strain(stimulus: Stimulus, depth_m: float, n_harmonics: int = 15) -> float:
    """Root-mean-square deviatoric strain (Frobenius norm, tensor shear) at depth, over a period.

    The sliding surface's strain comes from ``tactilab.forward.tractors.sliding_sinusoid_strain``
    (nu = 1/2); a square surface is the sum of its odd sine harmonics ``4 A / (n pi)`` of pitch
    ``p / n``. For a sinusoid the norm is constant in space and time and equals
    ``sqrt(2) (2 pi / p)^2 A Z exp(-2 pi Z / p)`` (docs/theory.md 4a).
    """
    if stimulus.amplitude_m == 0:
        return 0.0
    x = np.linspace(0.0, stimulus.pitch_m, 64, endpoint=False)
    if stimulus.surface == "sinusoid":
        parts = [(stimulus.amplitude_m, stimulus.pitch_m)]
    else:
        parts = [(4 * stimulus.amplitude_m / (n * math.pi), stimulus.pitch_m / n)
                 for n in range(1, 2 * n_harmonics, 2)]
    strain = sum(sliding_sinusoid_strain(x, depth_m, a, p) for a, p in parts)
    eps_xx, eps_yy, eps_zz, eps_yz, eps_zx, eps_xy = np.moveaxis(strain, -1, 0)
    mean = (eps_xx + eps_yy + eps_zz) / 3
    frob2 = ((eps_xx - mean) ** 2 + (eps_yy - mean) ** 2 + (eps_zz - mean) ** 2
             + 2 * (eps_yz ** 2 + eps_zx ** 2 + eps_xy ** 2))
    return float(np.sqrt(np.mean(frob2)))


def rendered_strain(stimulus: Stimulus, display) -> float:
    """RMS deviatoric strain that a simulated display ACTUALLY produces for a stimulus, at its depth.

    The drive is rendered and limited exactly as the runner's safety layer limits it
    (``display.steady_drive``), then the display's tractor model gives the strain at
    ``display.depth_m`` (Flamant line loads, nu = 1/2, tensor shear; ``eps_zz = -eps_xx``, so
    the deviatoric Frobenius norm squared is ``2 eps_xx^2 + 2 eps_xz^2``). The RMS is taken over
    the display's points and the frames between the onset and offset ramps. For a stimulus
    within the display's limits it matches :func:`receptor_strain` (the drive's gain is chosen
    for that); where the safety layer limits the drive it is smaller.

    Parameters
    ----------
    stimulus : Stimulus
        What is commanded (SI).
    display : SimulatedDisplay
        Supplies the description, depth, modulus and strain model.
    """
    steady = display.steady_drive(stimulus)
    eps_xx, eps_xz = display.strain(steady)
    return float(np.sqrt(np.mean(2 * eps_xx ** 2 + 2 * eps_xz ** 2)))


class SimulatedObserver(ResponseSource):
    """A model observer: strain at the receptors -> transducer -> Gaussian noise -> decision.

    Each stimulus gives ``d = (s / threshold_strain) ** exponent`` in units of the internal
    noise, where ``s`` is :func:`receptor_strain` (the ideal virtual surface), or with
    ``display=`` a simulated display, :func:`rendered_strain` (what that display really produces
    after the safety limits), or ``strain_fn(stimulus)``. The observation
    of a stimulus is the feature vector ``(d, d sign(V), frequency_acuity d_c log2(|V| / p))``
    (``d_c = min(d, 1)``: frequency is coded once the stimulus is felt) plus unit Gaussian noise.
    Decisions: yes/no says yes when ``d + n > criterion``; 2IFC picks the interval with the larger
    noisy ``d``; 2AFC picks the alternative whose noise-free features lie nearest the
    observation; same/different says different when the noisy feature distance exceeds
    ``criterion * sqrt(2)``; magnitude estimation reports ``round(min + gain * d + n)``, clipped.
    Response times: ``0.3 s + 0.4 s exp(-|margin|)`` times a lognormal factor (sd 0.2).

    Randomness: ``np.random.default_rng([seed, trial_index, 2])``, so a repeated trial gets the
    same answer and a resumed session matches an uninterrupted one.
    """

    name = "simulated"

    def __init__(self, protocol: Protocol, *, seed: int | None = None, threshold_strain: float = 2e-3,
                 exponent: float = 1.0, criterion: float = 1.0, frequency_acuity: float = 2.0,
                 magnitude_gain: float = 2.0, depth_m: float = 1e-3, display=None,
                 strain_fn: Callable[[Stimulus], float] | None = None, lapse: float = 0.0) -> None:
        threshold_strain = rules.positive(threshold_strain, "threshold_strain", "1")
        exponent = rules.positive(exponent, "exponent", "1")
        depth_m = rules.depth(depth_m, "depth_m")
        for name, value in (("criterion", criterion), ("frequency_acuity", frequency_acuity),
                            ("magnitude_gain", magnitude_gain)):
            if not math.isfinite(value):
                raise ValueError(f"{name}: must be finite, got {value!r}")
        if not (math.isfinite(lapse) and 0 <= lapse < 0.5):
            raise ValueError(f"lapse: must lie in [0, 0.5) (the drop of the upper asymptote), got {lapse!r}")
        self.lapse = float(lapse)
        self.protocol = protocol
        self.seed = protocol.seed if seed is None else int(seed)
        self.threshold_strain, self.exponent, self.criterion = threshold_strain, exponent, criterion
        self.frequency_acuity, self.magnitude_gain, self.depth_m = frequency_acuity, magnitude_gain, depth_m
        if strain_fn is not None:
            self.strain_source = "custom"
        elif display is not None:
            if not callable(getattr(display, "steady_drive", None)):
                raise ValueError(
                    f"display: the observer feels a display's strain only for a simulated display, got "
                    f"{type(display).__name__}; use the surface strain (display=None)"
                )
            self.strain_source, strain_fn = "display", (lambda s: rendered_strain(s, display))
        else:
            self.strain_source, strain_fn = "surface", (lambda s: receptor_strain(s, depth_m))
        self.strain_fn = strain_fn
        self._drives: dict[Stimulus, float] = {}

    @property
    def config(self) -> dict[str, float]:
        """The observer's parameters (recorded with the session so a resume uses the same observer)."""
        return {"strain": self.strain_source, "seed": self.seed, "threshold_strain": self.threshold_strain,
                "exponent": self.exponent,
                "criterion": self.criterion, "frequency_acuity": self.frequency_acuity,
                "magnitude_gain": self.magnitude_gain, "depth_m": self.depth_m,
                **({"lapse": self.lapse} if self.lapse else {})}

    def drive(self, stimulus: Stimulus) -> float:
        """Noise-free transducer output ``d`` of a stimulus (units of the noise sd)."""
        if stimulus not in self._drives:  # stimuli are frozen (hashable); levels repeat a lot
            self._drives[stimulus] = (self.strain_fn(stimulus) / self.threshold_strain) ** self.exponent
        return self._drives[stimulus]

    def features(self, stimulus: Stimulus) -> np.ndarray:
        """Noise-free feature vector of a stimulus, shape (3,)."""
        d = self.drive(stimulus)
        freq = abs(stimulus.speed_m_per_s) / stimulus.pitch_m
        code = math.log2(freq) if freq > 0 else 0.0
        return np.array([d, d * np.sign(stimulus.speed_m_per_s), self.frequency_acuity * min(d, 1.0) * code])

    def collect(self, plan):
        rng = np.random.default_rng([self.seed, plan.trial_index, 2])
        task = self.protocol.task
        obs = [self.features(s) + rng.standard_normal(3) for s in plan.stimuli]
        if task.kind == "2ifc":
            margin = obs[0][0] - obs[1][0]
            label = "1" if margin > 0 else "2"
        elif task.kind == "yes_no":
            margin = obs[0][0] - self.criterion
            label = "yes" if margin > 0 else "no"
        elif task.kind == "2afc":
            templates = {
                lab: self.features(Stimulus.model_validate(
                    {**self.protocol.stimulus.model_dump(), **over}).with_level(plan.parameter, plan.level))
                for lab, over in task.alternatives.items()}
            dist = {lab: float(np.linalg.norm(obs[0] - t)) for lab, t in templates.items()}
            a, b = task.labels
            margin = dist[b] - dist[a]
            label = a if margin > 0 else b
        elif task.kind == "same_different":
            margin = float(np.linalg.norm(obs[1] - obs[0])) - self.criterion * math.sqrt(2)
            label = "different" if margin > 0 else "same"
        else:
            value = task.magnitude_min + self.magnitude_gain * obs[0][0]
            rating = int(min(max(round(value), task.magnitude_min), task.magnitude_max))
            margin, label = 1.0, str(rating)
        if self.lapse and task.kind in ("2ifc", "2afc", "yes_no") and rng.random() < 2 * self.lapse:
            label = task.labels[int(rng.integers(2))]  # a lapse: a guess (P(correct) <= 1 - lapse)
        rt_s = (0.3 + 0.4 * math.exp(-abs(margin))) * math.exp(0.2 * rng.standard_normal())
        return Response(label, rt_s, self._onset_ns + int(rt_s * 1e9))

    @classmethod
    def from_model(cls, protocol: Protocol, model, threshold_strain: float, exponent: float = 1.0,
                   lapse: float = 0.0, seed: int | None = None) -> SimulatedObserver:
        """An observer that reads a transduction model (``tactilab.experiments.modelling.models.TransductionModel``).

        Its drive is ``d = (model.statistic_of(s) / threshold_strain) ** exponent``; it lapses
        (guesses) on a share ``2 lapse`` of 2IFC, 2AFC and yes/no trials, so that 2IFC P(correct)
        = 1/2 + (1/2 - lapse)(2 Phi(delta_d / sqrt 2) - 1), the model's own link; its yes/no
        criterion is 1 (false-alarm rate Phi(-1) = 0.159 without lapses).
        """
        if not callable(getattr(model, "statistic_of", None)):
            raise ValueError(f"model: expected a TransductionModel (with statistic_of), got {type(model).__name__}")
        return cls(protocol, seed=seed, threshold_strain=threshold_strain, exponent=exponent,
                   strain_fn=model.statistic_of, lapse=lapse)


def true_threshold_2ifc(observer: SimulatedObserver, protocol: Protocol, p_correct: float = 2 ** -0.5) -> float:
    """Amplitude (m) at which the observer is correct with ``p_correct`` in 2IFC against a blank.

    Signal detection: P(correct) = Phi(d / sqrt(2)), d = (s / s_threshold)^exponent, and the
    sinusoid's strain s = sqrt(2) (2 pi / p)^2 A Z exp(-2 pi Z / p) is linear in A.
    """
    d = math.sqrt(2) * float(ndtri(p_correct))
    strain = observer.threshold_strain * d ** (1 / observer.exponent)
    p, z = protocol.stimulus.pitch_m, observer.depth_m
    return strain / (math.sqrt(2) * (2 * math.pi / p) ** 2 * z * math.exp(-2 * math.pi * z / p))
