"""Sensor arrays inside the skin: where the sensors are and what each one measures.

Conventions (docs/theory.md section 1): x along the scan, y across it, z depth into the skin.
Sensor positions ``(x, y)`` are in the finger (skin) frame, in m; all sensors of an array sit at
the same depth ``depth_m`` > 0 below the surface.

Components are tensor components named from the closed set ``COMPONENTS`` (Voigt order
xx, yy, zz, yz, zx, xy). For strain they are TENSOR components eps_ij: the engineering shear
gamma_ij = 2 eps_ij is obtained with :func:`engineering_factors`. Stress is in Pa (tension
positive); strain is dimensionless (unit name ``"strain"``).
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import ValidationError, field_validator, model_validator

from tactilab.core import rules
from tactilab.core.rules import COMPONENTS  # noqa: F401 - the one Voigt order, re-exported for records

from .base import Record, at_least, finite, float_array, format_validation_error, non_negative, positive

QUANTITY_UNITS: dict[str, str] = {"stress": "Pa", "strain": "strain"}
"""The unit of each measured quantity (stress in Pa, strain dimensionless)."""


def check_components(components, field: str = "components") -> tuple[str, ...]:
    """Validate component names: a non-empty list from ``COMPONENTS``, no repeats; aliases accepted.

    The rule is :func:`tactilab.core.rules.components`, the solver's: ``xz``, ``zy`` and ``yx``
    name the same tensor entries as ``zx``, ``yz`` and ``xy`` (the tensors are symmetric) and
    come back under those names. A record field is a list, so a bare string is refused.

    Returns
    -------
    tuple of str
        Canonical names, in the order given.

    Raises
    ------
    ValueError
        Naming ``field``, the offending name and the valid names.
    """
    if isinstance(components, str):
        raise ValueError(
            f"{field} must be a list of component names, got the string {components!r}; "
            f"write e.g. [{components!r}]"
        )
    return rules.components(components, field)


def voigt_indices(components) -> np.ndarray:
    """Indices of ``components`` in the Voigt order ``COMPONENTS``, shape (n_components,)."""
    return np.array([COMPONENTS.index(c) for c in check_components(components)], dtype=int)


def engineering_factors(components) -> np.ndarray:
    """Factors that turn tensor strain into engineering (Voigt) strain, shape (n_components,).

    1 for normal components, 2 for shear (gamma_ij = 2 eps_ij). Multiply tensor strain by
    these factors; divide engineering strain by them to get tensor strain.
    """
    return np.array([1.0 if c[0] == c[1] else 2.0 for c in check_components(components)])


class SensorGrid(Record):
    """A rectangular grid of sensor positions, centred on ``center_m``.

    Used by :meth:`SensorArray.grid` and by ``[sensors.grid]`` tables in scene files.

    Parameters
    ----------
    nx, ny : int
        Number of sensors along x and y (>= 1).
    spacing_x_m, spacing_y_m : float, m
        Sensor spacing along x and y (> 0). ``spacing_y_m`` defaults to ``spacing_x_m``.
    center_m : (float, float), m
        Centre of the grid.
    """

    nx: Annotated[int, at_least(1, "sensors along x")]
    ny: Annotated[int, at_least(1, "sensors along y")] = 1
    spacing_x_m: Annotated[float, positive("the distance between neighbouring sensors")]
    spacing_y_m: Annotated[float, positive("the distance between neighbouring sensors")] | None = None
    center_m: tuple[Annotated[float, finite()], Annotated[float, finite()]] = (0.0, 0.0)

    def positions_m(self) -> np.ndarray:
        """Sensor positions (x, y), shape (nx * ny, 2), m, row-major (y varies slowest)."""
        dy = self.spacing_y_m if self.spacing_y_m is not None else self.spacing_x_m
        x = self.center_m[0] + (np.arange(self.nx) - (self.nx - 1) / 2.0) * self.spacing_x_m
        y = self.center_m[1] + (np.arange(self.ny) - (self.ny - 1) / 2.0) * dy
        gx, gy = np.meshgrid(x, y)
        return np.column_stack([gx.ravel(), gy.ravel()])


class SensorArray(Record):
    """Sensors at one depth in the skin, each measuring the same tensor components.

    Parameters
    ----------
    positions_m : array_like, shape (n_sensors, 2), m
        Sensor positions (x, y) in the finger frame.
    depth_m : float, m
        Depth of the sensors below the skin surface, > 0 (0.5 to 3 mm in a finger).
    quantity : {"stress", "strain"}
        What the sensors measure.
    components : sequence of str
        Measured components from ``COMPONENTS`` (tensor components; see module docstring).
    noise_std : float
        Standard deviation of the additive measurement noise per sample, >= 0, in the unit
        of ``quantity``: Pa for stress, dimensionless for strain (see :attr:`unit`).
    sensor_ids : sequence of str, optional
        One unique name per sensor; default ``"s0", "s1", ...`` (see :attr:`ids`).
    name : str
        Free label.
    """

    positions_m: float_array(2, 2, "sensor (x, y) positions")
    depth_m: Annotated[float, positive(
        "sensors sit inside the skin", "give the depth below the surface as a positive number in m")]
    quantity: Literal["stress", "strain"] = "stress"
    components: tuple[str, ...]
    noise_std: Annotated[float, non_negative(
        "a standard deviation", "give the noise level in Pa (stress) or strain, or 0 for none")] = 0.0
    sensor_ids: tuple[str, ...] | None = None
    name: str = ""

    @field_validator("components", mode="before")
    @classmethod
    def _known_components(cls, value):
        return check_components(value)

    @model_validator(mode="after")
    def _ids_match_positions(self) -> SensorArray:
        n = self.positions_m.shape[0]
        if self.sensor_ids is not None:
            if len(self.sensor_ids) != n:
                raise ValueError(
                    f"sensor_ids has {len(self.sensor_ids)} entries but positions_m has shape "
                    f"{self.positions_m.shape}; give one id per sensor row"
                )
            repeated = sorted({s for s in self.sensor_ids if self.sensor_ids.count(s) > 1})
            if repeated:
                raise ValueError(f"sensor_ids must be unique, got {repeated} more than once; rename them")
        return self

    @classmethod
    def _edge_prepare(cls, data: dict, where: str) -> tuple[dict, dict[str, str]]:
        """File-edge hook: expand a ``grid`` table into ``positions_m``; give noise_std's dimension."""
        dimensions = {"noise_std": "pressure" if data.get("quantity", "stress") == "stress" else "dimensionless"}
        if "grid" not in data:
            return data, dimensions
        here = f"{where}.grid" if where else "grid"
        given = [k for k in data if k.startswith("positions")]
        if given:
            raise ValueError(f"{here}: both a grid and {given[0]} are given; keep one way of placing the sensors")
        raw = data["grid"]
        if not isinstance(raw, dict):
            raise ValueError(f"{here} must be a table with nx, ny, spacing_x, ..., got {raw!r}; "
                             "write [sensors.grid] with nx = 10, spacing_x = \"1mm\"")
        from .unit_keys import convert_units

        try:
            layout = SensorGrid.model_validate(convert_units(SensorGrid, raw, here))
        except ValidationError as err:
            raise ValueError(format_validation_error(err, here)) from None
        data = {k: v for k, v in data.items() if k != "grid"}
        data["positions_m"] = layout.positions_m().tolist()
        return data, dimensions

    @property
    def n_sensors(self) -> int:
        """Number of sensors."""
        return int(self.positions_m.shape[0])

    @property
    def n_components(self) -> int:
        """Number of measured components."""
        return len(self.components)

    @property
    def unit(self) -> str:
        """Unit of the measured values and of ``noise_std``: ``"Pa"`` or ``"strain"`` (tensor shear eps_ij)."""
        return QUANTITY_UNITS[self.quantity]

    @property
    def ids(self) -> tuple[str, ...]:
        """Sensor names: ``sensor_ids`` if given, else ``("s0", "s1", ...)``."""
        if self.sensor_ids is not None:
            return self.sensor_ids
        return tuple(f"s{i}" for i in range(self.n_sensors))

    @property
    def voigt_indices(self) -> np.ndarray:
        """Indices of the measured components in Voigt order, shape (n_components,)."""
        return voigt_indices(self.components)

    @classmethod
    def grid(cls, nx: int, ny: int, spacing_x_m: float, depth_m: float, *,
             spacing_y_m: float | None = None, center_m: tuple[float, float] = (0.0, 0.0),
             **fields) -> SensorArray:
        """A rectangular ``nx`` x ``ny`` grid of sensors (see :class:`SensorGrid`).

        ``fields`` are the other :class:`SensorArray` fields (``components``, ``quantity``, ...).
        """
        layout = SensorGrid(nx=nx, ny=ny, spacing_x_m=spacing_x_m, spacing_y_m=spacing_y_m,
                            center_m=center_m)
        return cls(positions_m=layout.positions_m(), depth_m=depth_m, **fields)
