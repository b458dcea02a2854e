"""The ``[procedure]`` table of an adaptive model-discrimination protocol (``method = "model_discrimination"``).

A protocol names the receptor hypotheses to tell apart as strings (``"zx@1mm"``; the grammar of
:mod:`tactilab.data_schemas.hypothesis`, checked here for syntax only) and the candidate stimuli
as parameter lists with units, e.g.::

    [procedure]
    method = "model_discrimination"
    parameter = "amplitude_m"
    models = ["zx@1mm", "zx@2mm"]
    max_trials = 300
    [procedure.candidates]
    amplitude_m = { start = "2um", stop = "100um", n = 20, scale = "log" }
    pitch_m = ["3mm"]
    speed_m_per_s = ["40mm/s"]

The candidates are the product of the lists; several fields may take several values (pitch,
amplitude and ``surface = ["sinusoid", "square"]``, say). Each trial shows the chosen candidate:
the protocol's ``[stimulus]`` with EVERY listed field set to the candidate's value (the runner's
``PlannedStimulus``; surface, amplitude and pitch always come from the candidate), so the
fields the procedure predicts with are the fields commanded. The
trial's recorded ``level`` is the candidate's value of ``parameter``. Each candidate is
validated on its own here, and merged with ``[stimulus]`` by the protocol at load
(:meth:`ModelDiscriminationConfig.planned_fields`). The procedure is
registered by :mod:`tactilab.experiments.design` (import it before loading such a protocol).
"""

from __future__ import annotations

import itertools
from typing import Any, ClassVar, Literal

from pydantic import Field, model_validator

from .experiment_procedures import PARAMETERS, ProcedureConfigBase, register_procedure_config
from .protocol_levels import grid
from .hypothesis import parse_hypothesis
from .stimulus import Stimulus

#: stimulus fields a candidate list may name, with their dimension ("text" for the waveform)
MAX_CANDIDATES = 1000  # the design's table is candidates x models x grid points
CANDIDATE_FIELDS = {**PARAMETERS, "surface": "text", "ramp_s": "time", "frame_rate_hz": "frequency"}
_DEFAULTS = ", ".join(f"{k} {Stimulus.model_fields[k].default!r}" for k in ("duration_s", "ramp_s", "frame_rate_hz"))


class ModelDiscriminationConfig(ProcedureConfigBase):
    """Adaptive selection of the candidate that best separates the hypotheses (see docs/adaptive_design.md)."""

    method: Literal["model_discrimination"]
    parameter: str
    models: list[str] = Field(min_length=2, max_length=32)
    candidates: dict[str, list[Any]]
    task: Literal["2ifc"] = "2ifc"
    utility: Literal["model", "odds", "parameters", "both"] = "model"
    n_grid: int = Field(25, ge=2, le=200, description="threshold grid points (log-spaced)")
    stop_probability: float = Field(0.99, gt=0.5, lt=1.0)
    max_trials: int = Field(500, ge=1, le=10_000)
    dropped: list[int] = Field(default_factory=list, description="candidates left out (their index in the "
                               "product of the lists), e.g. those the display would clip (clipped = 'drop')")

    @model_validator(mode="before")
    @classmethod
    def _units(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        if data.get("parameter") not in PARAMETERS:
            raise ValueError(f"parameter: must be one of {sorted(PARAMETERS)}, got {data.get('parameter')!r}; "
                             "name the stimulus field the runner varies")
        raw = data.get("candidates")
        if not isinstance(raw, dict) or not raw:
            raise ValueError("candidates: the candidate set is empty; give parameter lists with units, e.g. "
                             "{amplitude_m = ['5um', '10um'], pitch_m = ['3mm'], speed_m_per_s = ['40mm/s']}")
        out = {}
        for key, values in raw.items():
            if key not in CANDIDATE_FIELDS:
                raise ValueError(f"candidates.{key}: unknown stimulus field; use {sorted(CANDIDATE_FIELDS)}")
            if CANDIDATE_FIELDS[key] == "text":
                if not isinstance(values, list) or not values or any(v not in ("sinusoid", "square") for v in values):
                    raise ValueError(f"candidates.surface: a list of 'sinusoid' or 'square', got {values!r}")
                out[key] = list(values)
            else:
                out[key] = grid(values, CANDIDATE_FIELDS[key], f"candidates.{key}")
        return {**data, "candidates": out}

    @model_validator(mode="after")
    def _check(self) -> ModelDiscriminationConfig:
        for i, text in enumerate(self.models):
            try:
                parse_hypothesis(text)
            except ValueError as exc:
                raise ValueError(f"models[{i}]: {exc}") from None
        missing = {"amplitude_m", "pitch_m", "speed_m_per_s"} - set(self.candidates)
        if missing:
            raise ValueError(f"candidates: need {sorted(missing)} too (one value each is enough), to predict "
                             "each hypothesis's strain")
        if self.parameter not in self.candidates:
            raise ValueError(f"candidates: must list the varied parameter {self.parameter!r}")
        n = 1
        for values in self.candidates.values():
            n *= len(values)
        if n > MAX_CANDIDATES:
            raise ValueError(f"candidates: the lists give {n} candidates (their product), above the cap of "
                             f"{MAX_CANDIDATES}; use fewer values per field")
        for i, combo in enumerate(itertools.product(*self.candidates.values())):
            try:  # on its own: the design predicts with it before any [stimulus] is known
                Stimulus.model_validate(dict(zip(self.candidates, combo)))
            except ValueError as exc:
                raise ValueError(
                    f"candidates: candidate {i} {dict(zip(self.candidates, combo))} is not a valid stimulus on its "
                    f"own ({exc.errors()[0]['msg'] if hasattr(exc, 'errors') else exc}; unlisted fields at their "
                    f"defaults: {_DEFAULTS}); change the lists, or list the timing fields together") from None
        bad = [i for i in self.dropped if not 0 <= i < n]
        if bad or len(set(self.dropped)) != len(self.dropped) or len(self.dropped) >= n:
            raise ValueError(f"dropped: must be distinct candidate indices in [0, {n}) leaving at least one "
                             f"candidate, got {self.dropped!r}; list each candidate to leave out once")
        return self

    #: the fix an error about an invalid merged candidate suggests (data_schemas.experiment.Protocol)
    planned_fix: ClassVar[str] = "change the candidate lists or [stimulus]"

    def planned_fields(self) -> list[tuple[str, dict[str, Any]]]:
        """Each candidate as the fields a trial sets on ``[stimulus]`` (SI), in the product order
        of the lists (candidate 0 first): every listed field, and surface, amplitude and pitch
        always (the candidate's own, its default waveform when unlisted), as the runner's
        ``PlannedStimulus`` carries them."""
        keys = tuple(dict.fromkeys(("surface", "amplitude_m", "pitch_m", *self.candidates)))
        out = []
        for i, s in self._kept():
            fields = {k: getattr(s, k) for k in keys}
            shown = ", ".join(f"{k}={v!r}" for k, v in fields.items())
            out.append((f"procedure.candidates[{i}] ({shown}) merged with [stimulus]", fields))
        return out

    def _kept(self) -> list[tuple[int, Stimulus]]:
        """``(index in the product, stimulus)`` of each candidate not :attr:`dropped`."""
        keys, dropped = list(self.candidates), set(self.dropped)
        return [(i, Stimulus.model_validate(dict(zip(keys, combo))))
                for i, combo in enumerate(itertools.product(*(self.candidates[k] for k in keys))) if i not in dropped]

    def stimuli(self) -> list[Stimulus]:
        """The candidate stimuli (the product of the lists, in the file's order, less those
        :attr:`dropped`), validated, SI."""
        return [s for _, s in self._kept()]

    def without_planned(self, indices: set[int]) -> ModelDiscriminationConfig:
        """This design without the candidates at ``indices`` of :meth:`planned_fields` (recorded
        in :attr:`dropped` by their index in the product, so a resumed session rebuilds the same set)."""
        kept = self._kept()
        if len(set(indices)) >= len(kept):
            raise ValueError(f"clipped: the display would limit all {len(kept)} candidates; nothing is left to "
                             "run; lower the candidates or pick a display that plays them")
        dropped = sorted({*self.dropped, *(kept[j][0] for j in indices)})
        return type(self).model_validate({**self.model_dump(), "dropped": dropped})

    def candidate_levels(self) -> list[float]:
        return [float(v) for v in self.candidates[self.parameter]]

    def n_planned(self) -> int:
        return self.max_trials


register_procedure_config("model_discrimination", ModelDiscriminationConfig)
