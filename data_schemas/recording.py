"""Recordings: sensor time series with sampling rate, units, sensor names and components.

A :class:`Recording` holds ``values`` of shape ``(n_times, n_sensors, n_components)`` in SI:
stress in Pa, strain dimensionless (tensor components; see :mod:`.sensors` for the shear
convention). Sample ``i`` is taken at ``start_time_s + i / sampling_rate_hz``.

Tidy form (:meth:`Recording.to_dataframe` / :meth:`Recording.from_dataframe`): one row per
sample, sensor and component, columns ``time_s, sensor, component, value``; the scalar fields
ride along in ``DataFrame.attrs``.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

import numpy as np
import pandas as pd
from pydantic import field_validator, model_validator

from tactilab.core.rules import COMPONENT_ALIASES

from .base import Record, finite, float_array, positive
from .sensors import QUANTITY_UNITS, SensorArray, check_components
from .units import to_si

TIDY_COLUMNS: tuple[str, ...] = ("time_s", "sensor", "component", "value")
"""Columns of the tidy DataFrame form."""


def _si_factor(unit: str, quantity: str, field: str) -> float:
    """Factor turning values in ``unit`` into the SI unit of ``quantity``."""
    if quantity == "strain":
        if unit in ("strain", "1", ""):
            return 1.0
        raise ValueError(
            f"{field} {unit!r} is not a unit of strain; strain is dimensionless: give unit 'strain'"
        )
    return to_si(f"1{unit}", "pressure", name=field)


def _order(given, found: tuple[str, ...], column: str) -> tuple[str, ...]:
    """The axis order: ``given`` if not None (it must list exactly the names found), else ``found``."""
    if given is None:
        return found
    given = tuple(str(g) for g in given)
    if sorted(given) != sorted(found):
        raise ValueError(
            f"the {column} column holds {sorted(found)} but the {column} order given is {list(given)}; "
            f"list each {column} of the data once"
        )
    return given


class Recording(Record):
    """Sensor time series.

    Parameters
    ----------
    values : array_like, shape (n_times, n_sensors, n_components)
        Measured values in ``unit`` (Pa or strain).
    sampling_rate_hz : float, Hz
        Samples per second, > 0.
    sensor_ids : sequence of str, length n_sensors
        Unique sensor names, in the order of axis 1.
    components : sequence of str, length n_components
        Component names (``COMPONENTS``), in the order of axis 2.
    quantity : {"stress", "strain"}
        What was measured.
    unit : {"Pa", "strain"}
        The SI unit of ``quantity`` (filled in when omitted). Other units are converted at the
        edges (:meth:`from_dataframe`), never stored.
    start_time_s : float, s
        Time of the first sample.
    description : str
        Free text: where the data came from.
    """

    values: float_array(3, reason="shape (n_times, n_sensors, n_components)")
    sampling_rate_hz: Annotated[float, positive("samples per second")]
    sensor_ids: tuple[str, ...]
    components: tuple[str, ...]
    quantity: Literal["stress", "strain"] = "stress"
    unit: str
    start_time_s: Annotated[float, finite()] = 0.0
    description: str = ""

    @model_validator(mode="before")
    @classmethod
    def _default_unit(cls, data: Any) -> Any:
        if isinstance(data, dict) and data.get("unit") is None:
            quantity = data.get("quantity", "stress")
            if quantity in QUANTITY_UNITS:
                data = {**data, "unit": QUANTITY_UNITS[quantity]}
        return data

    @field_validator("components", mode="before")
    @classmethod
    def _known_components(cls, value):
        return check_components(value)

    @model_validator(mode="after")
    def _consistent(self) -> Recording:
        want = QUANTITY_UNITS[self.quantity]
        if self.unit != want:
            _si_factor(self.unit, self.quantity, "unit")  # unknown or wrong-dimension unit: its own message
            raise ValueError(
                f"unit must be the SI unit {want!r} for quantity {self.quantity!r}, got {self.unit!r}; "
                f"convert the values to {want} (Recording.from_dataframe(..., unit={self.unit!r}) does it)"
            )
        shape = self.values.shape
        if shape[1] != len(self.sensor_ids):
            raise ValueError(
                f"values has shape {shape} (n_times, n_sensors, n_components) but sensor_ids has "
                f"{len(self.sensor_ids)} entries; give one id per sensor (axis 1)"
            )
        if shape[2] != len(self.components):
            raise ValueError(
                f"values has shape {shape} (n_times, n_sensors, n_components) but components has "
                f"{len(self.components)} entries; give one name per component (axis 2)"
            )
        repeated = sorted({s for s in self.sensor_ids if self.sensor_ids.count(s) > 1})
        if repeated:
            raise ValueError(f"sensor_ids must be unique, got {repeated} more than once; rename them")
        return self

    # ----- shape and time ---------------------------------------------------------------
    @property
    def n_times(self) -> int:
        """Number of samples."""
        return int(self.values.shape[0])

    @property
    def n_sensors(self) -> int:
        """Number of sensors."""
        return int(self.values.shape[1])

    @property
    def n_components(self) -> int:
        """Number of components."""
        return int(self.values.shape[2])

    @property
    def times_s(self) -> np.ndarray:
        """Sample times, shape (n_times,), s."""
        return self.start_time_s + np.arange(self.n_times) / self.sampling_rate_hz

    @property
    def duration_s(self) -> float:
        """Recorded time span, ``n_times / sampling_rate_hz`` (s)."""
        return self.n_times / self.sampling_rate_hz

    def series(self, sensor: str, component: str) -> np.ndarray:
        """One sensor's time series for one component, shape (n_times,), in ``unit``."""
        if sensor not in self.sensor_ids:
            raise ValueError(f"sensor {sensor!r} is not in this recording; use one of {list(self.sensor_ids)}")
        if component not in self.components:
            raise ValueError(
                f"component {component!r} is not in this recording; use one of {list(self.components)}"
            )
        return self.values[:, self.sensor_ids.index(sensor), self.components.index(component)]

    # ----- sensors ----------------------------------------------------------------------
    @classmethod
    def from_sensors(cls, sensors: SensorArray, values, sampling_rate_hz: float,
                     start_time_s: float = 0.0, description: str = "") -> Recording:
        """Build a recording whose ids, components and quantity are those of ``sensors``."""
        return cls(values=values, sampling_rate_hz=sampling_rate_hz, sensor_ids=sensors.ids,
                   components=sensors.components, quantity=sensors.quantity,
                   start_time_s=start_time_s, description=description)

    def check_matches(self, sensors: SensorArray) -> None:
        """Raise ValueError unless ids, components and quantity agree with ``sensors``."""
        for field, mine, theirs in (("sensor_ids", self.sensor_ids, sensors.ids),
                                    ("components", self.components, sensors.components),
                                    ("quantity", self.quantity, sensors.quantity)):
            if mine != theirs:
                raise ValueError(
                    f"recording {field} {mine!r} does not match the sensor array's {theirs!r}; "
                    "record with the same sensors or build it with Recording.from_sensors"
                )

    # ----- tidy DataFrame -----------------------------------------------------------------
    def to_dataframe(self) -> pd.DataFrame:
        """Tidy form: one row per (time, sensor, component), columns ``TIDY_COLUMNS``.

        Rows are ordered by time, then sensor, then component; ``attrs`` carries
        ``sampling_rate_hz``, ``start_time_s``, ``quantity``, ``unit``, ``description``,
        ``sensor_ids`` and ``components`` (their order).
        """
        nt, ns, nc = self.values.shape
        df = pd.DataFrame({
            "time_s": np.repeat(self.times_s, ns * nc),
            "sensor": np.tile(np.repeat(np.array(self.sensor_ids, dtype=object), nc), nt),
            "component": np.tile(np.array(self.components, dtype=object), nt * ns),
            "value": self.values.ravel().copy(),
        })
        df.attrs.update(sampling_rate_hz=self.sampling_rate_hz, start_time_s=self.start_time_s,
                        quantity=self.quantity, unit=self.unit, description=self.description,
                        sensor_ids=self.sensor_ids, components=self.components)
        return df

    @classmethod
    def from_dataframe(cls, df: pd.DataFrame, *, sampling_rate_hz: float | None = None,
                       quantity: str | None = None, unit: str | None = None,
                       start_time_s: float | None = None, description: str | None = None,
                       sensor_ids=None, components=None) -> Recording:
        """Build a recording from the tidy form written by :meth:`to_dataframe`.

        Arguments left as None are read from ``df.attrs``; failing that, ``sampling_rate_hz``
        and ``start_time_s`` are inferred from the ``time_s`` column (uniform sampling; the
        inferred rate is rounded to 10 significant digits), ``quantity`` defaults to
        ``"stress"`` and ``unit`` to its SI unit. Values in another unit (``unit="kPa"``)
        are converted to SI once, here. ``sensor_ids`` and ``components`` fix the order of
        axes 1 and 2; without them (and without ``attrs``) sensors and components keep their
        order of first appearance.

        Raises
        ------
        ValueError
            Missing columns, an unknown unit, non-uniform or too few times, a duplicated or
            missing (time, sensor, component) row.
        """
        missing = [c for c in TIDY_COLUMNS if c not in df.columns]
        if missing:
            raise ValueError(f"df lacks the columns {missing} (tidy form); give columns {list(TIDY_COLUMNS)}")
        if len(df) == 0:
            raise ValueError("df has no rows; give at least one sample")
        attrs = df.attrs
        quantity = quantity if quantity is not None else attrs.get("quantity", "stress")
        if quantity not in QUANTITY_UNITS:
            raise ValueError(f"quantity must be 'stress' or 'strain', got {quantity!r}; pick one")
        unit = unit if unit is not None else attrs.get("unit", QUANTITY_UNITS[quantity])
        factor = _si_factor(unit, quantity, "unit")
        times = df["time_s"].to_numpy(dtype=float)
        if not np.isfinite(times).all():
            raise ValueError("time_s must be finite, got NaN or inf; fix the time column")
        unique_t = np.unique(times)
        t0 = start_time_s if start_time_s is not None else attrs.get("start_time_s", float(unique_t[0]))
        rate = sampling_rate_hz if sampling_rate_hz is not None else attrs.get("sampling_rate_hz")
        if rate is None:
            if len(unique_t) < 2:
                raise ValueError("time_s has a single value, so the sampling rate is unknown; "
                                 "pass sampling_rate_hz")
            rate = float(f"{(len(unique_t) - 1) / (unique_t[-1] - unique_t[0]):.10g}")
        rate = float(rate)
        if not (np.isfinite(rate) and rate > 0):
            raise ValueError(f"sampling_rate_hz must be > 0, got {rate!r}; give samples per second")
        position = (times - t0) * rate
        index_t = np.rint(position).astype(np.int64)
        off = np.abs(position - index_t)
        if off.max() > 1e-6 or index_t.min() < 0:
            bad = int(np.argmax(off)) if off.max() > 1e-6 else int(np.argmin(index_t))
            raise ValueError(
                f"time_s must be uniformly sampled at {rate!r} Hz from {t0!r} s, but row {bad} has "
                f"time {times[bad]!r} s; resample the data or pass the right sampling_rate_hz"
            )
        found_s = tuple(str(s) for s in pd.unique(df["sensor"].astype(str)))
        component = df["component"].astype(str).replace(COMPONENT_ALIASES)  # 'xz' is 'zx', as everywhere
        found_c = check_components(tuple(pd.unique(component)), "component column")
        sensors = _order(sensor_ids if sensor_ids is not None else attrs.get("sensor_ids"), found_s, "sensor")
        given_c = components if components is not None else attrs.get("components")
        components = _order(None if given_c is None else check_components(given_c, "components"), found_c, "component")
        index_s = pd.Index(sensors).get_indexer(df["sensor"].astype(str))
        index_c = pd.Index(components).get_indexer(component)
        shape = (int(index_t.max()) + 1, len(sensors), len(components))
        flat = np.ravel_multi_index((index_t, index_s, index_c), shape)
        counts = np.bincount(flat, minlength=int(np.prod(shape)))
        if (counts > 1).any():
            t, s, c = np.unravel_index(int(np.argmax(counts > 1)), shape)
            raise ValueError(
                f"df has {counts.max()} rows for time {t0 + t / rate!r} s, sensor {sensors[s]!r}, "
                f"component {components[c]!r}; give each (time, sensor, component) once"
            )
        if (counts == 0).any():
            t, s, c = np.unravel_index(int(np.argmax(counts == 0)), shape)
            raise ValueError(
                f"df has no row for time {t0 + t / rate!r} s, sensor {sensors[s]!r}, component "
                f"{components[c]!r}; give every (time, sensor, component) combination"
            )
        values = np.empty(int(np.prod(shape)))
        values[flat] = df["value"].to_numpy(dtype=float) * factor
        return cls(values=values.reshape(shape), sampling_rate_hz=rate, sensor_ids=sensors,
                   components=components, quantity=quantity, start_time_s=t0,
                   description=description if description is not None else attrs.get("description", ""))
