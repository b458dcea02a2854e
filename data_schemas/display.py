"""Laterotactile displays: tractor geometry and per-tractor limits.

A laterotactile display presses a grid of small contactors ("tractors") on the skin and moves
them sideways, applying tangential tractions (or deflections) to the skin surface. Geometry
follows the project conventions: x is the scanning direction (tractors move along x), y is
across it; SI units throughout (m, Pa, s, Hz).

Tractor ``(row, column)`` sits at ``x = center_x + (column - (columns - 1) / 2) * pitch_x_m``,
``y = center_y + (row - (rows - 1) / 2) * pitch_y_m``; arrays over tractors are row-major,
shape ``(rows, columns)``. In the plane model of docs/theory.md 4a a tractor pair spaced
``2 d`` apart is a uniform row with ``pitch_x_m = 2 d`` (:attr:`DisplayDescription.half_spacing_m`).
"""

from __future__ import annotations

import pathlib
from pathlib import PurePath
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, PrivateAttr, field_validator, model_validator

from .base import Record, at_least, finite, in_range, positive
from .paths import file_inside

Length = Annotated[float, positive()]


# Nominal drive limits shared by the presets (not confirmed from a source; override per display).
_NOMINAL_LIMITS = dict(motion_axes="x", max_traction_pa=50e3, max_deflection_m=0.1e-3,
                       max_slew_rate_per_s=2000.0, max_duty_cycle=1.0, frame_rate_hz=1000.0)
#: How far ahead of its due time a UDP host sends each frame by default, s (docs/udp-frame-format.md).
DEFAULT_LOOKAHEAD_S = 0.05
#: The longest lookahead a description may ask for, s (a device's FIFO holds about 1 s).
MAX_LOOKAHEAD_S = 0.5
#: The link fields: how a host reaches the display, not what the display is (left out of a
#: session's record of the description while they hold their defaults, so older records match).
LINK_FIELDS = {"pairing_key_file": None, "lookahead_s": DEFAULT_LOOKAHEAD_S}


class DisplayDescription(Record):
    """A tractor array and the limits of each tractor.

    Parameters
    ----------
    display_id : str
        Name of the device, e.g. ``"STReSS2"``.
    rows, columns : int
        Number of tractors across (y) and along (x) the scanning direction, both >= 1.
    pitch_x_m, pitch_y_m : float, m
        Centre-to-centre spacing of the tractors along x and y. ``pitch_y_m`` may be omitted
        (``None``) only for a one-row display.
    tractor_width_m, tractor_length_m : float, m
        Contact footprint of one tractor along x (its contact width) and along y; each must not
        exceed the matching pitch, or neighbours would overlap.
    motion_axes : {"x", "xy"}
        Directions in which a tractor moves (``"x"``: laterally along the scanning direction).
    max_traction_pa : float or None, Pa
        Largest tangential traction a tractor can apply to the skin.
    max_deflection_m : float or None, m
        Largest lateral deflection of a tractor from rest. At least one of the two limits is
        required.
    max_slew_rate_per_s : float or None, 1/s
        Largest rate of change of a tractor command, in full-scale units per second (the
        full scale is ``max_traction_pa`` or ``max_deflection_m``); ``None`` for no limit.
    max_duty_cycle : float in (0, 1]
        Largest fraction of frames in which one tractor may be driven (non-zero command).
    frame_rate_hz : float, Hz
        Rate at which the display refreshes all tractor commands.
    center_m : (float, float), m
        Position (x, y) of the array centre on the skin.
    description : str
        Free text: the source of the numbers.
    pairing_key_file : str or None
        The 32-byte pairing key shared with a UDP display (docs/udp-frame-format.md): a file name
        relative to the folder of the description's JSON file (inside it, no symlink, readable
        by its owner only). Only a host holding this key can arm the display.
    lookahead_s : float, s
        How far ahead of its due time a UDP host sends each frame into the device's FIFO, in
        [0, 0.5] s (default 0.05; ``"lookahead_ms": 50`` in a file). Host jitter up to the
        lookahead skips nothing; with the host dead, the device's outputs are zero at most
        ``lookahead_s`` plus its watchdog time after the host's last message.
    """

    display_id: Annotated[str, Field(min_length=1)]
    rows: Annotated[int, at_least(1, "a display has at least one row of tractors")]
    columns: Annotated[int, at_least(1, "a row has at least one tractor")]
    pitch_x_m: Length
    pitch_y_m: Length | None = None
    tractor_width_m: Length
    tractor_length_m: Length
    motion_axes: Literal["x", "xy"] = "x"
    max_traction_pa: Annotated[float, positive("a traction limit")] | None = None
    max_deflection_m: Annotated[float, positive("a deflection limit")] | None = None
    max_slew_rate_per_s: Annotated[float, positive("full-scale units per second")] | None = None
    max_duty_cycle: Annotated[float, in_range(0.0, 1.0, low_open=True,
                                              reason="a fraction of the frames")] = 1.0
    frame_rate_hz: Annotated[float, positive("the display refresh rate")]
    center_m: tuple[Annotated[float, finite()], Annotated[float, finite()]] = (0.0, 0.0)
    description: str = ""
    pairing_key_file: str | None = None
    lookahead_s: Annotated[float, in_range(0.0, MAX_LOOKAHEAD_S, reason="how far ahead frames are sent")] = \
        DEFAULT_LOOKAHEAD_S
    #: the folder of the JSON file this description was loaded from (None: built in Python)
    _folder: pathlib.Path | None = PrivateAttr(default=None)

    @field_validator("pairing_key_file")
    @classmethod
    def _key_file_name(cls, value: str | None) -> str | None:
        if value is not None and (not value or "\x00" in value or PurePath(value).is_absolute()
                                  or ".." in PurePath(value).parts):
            raise ValueError(f"pairing_key_file must be a file name relative to the description's folder, with no "
                             f"'..', got {value!r}; put the key file next to the description")
        return value

    @classmethod
    def load(cls, path: str | pathlib.Path) -> DisplayDescription:
        """Read a description saved as JSON; its ``pairing_key_file`` is relative to this file's folder."""
        description = super().load(path)
        description._folder = pathlib.Path(path).parent
        return description

    def replace(self, **changes) -> DisplayDescription:
        """A copy with some fields changed, validated again; it keeps the folder of the file it was read from."""
        copy = super().replace(**changes)
        copy._folder = self._folder
        return copy

    def pairing_key_path(self) -> pathlib.Path:
        """The checked path of ``pairing_key_file`` (inside the description's folder, a regular file, no symlink).

        Raises
        ------
        ValueError
            No ``pairing_key_file``, a description not read from a file (its folder is unknown),
            or a path that leaves the folder, passes a symlink or is no regular file.
        """
        if self.pairing_key_file is None:
            raise ValueError(f"pairing_key_file: display {self.display_id!r} names no pairing key; a UDP display "
                             "(frame format version 3) needs one: create it with `tactilab device pair KEYFILE`, "
                             "name it in the description's pairing_key_file and give the same file to the device")
        if self._folder is None:
            raise ValueError(f"pairing_key_file: {self.pairing_key_file!r} is relative to the description's JSON file, "
                             "but this description was not read from one (e.g. a session's recorded copy); give "
                             "the description file (`--device FILE`)")
        return file_inside(self._folder, self.pairing_key_file, key="pairing_key_file", owner="description",
                           what="key file")

    @field_validator("display_id")
    @classmethod
    def _id_not_blank(cls, value: str) -> str:
        if not value.strip():
            raise ValueError(f"display_id must not be blank, got {value!r}; name the device, e.g. 'STReSS2'")
        return value

    @model_validator(mode="after")
    def _check_geometry(self) -> DisplayDescription:
        if self.max_traction_pa is None and self.max_deflection_m is None:
            raise ValueError(
                "max_traction_pa and max_deflection_m are both missing (a tractor has a limit); "
                "give at least one of them: max_traction_pa in Pa or max_deflection_m in m"
            )
        if self.rows > 1 and self.pitch_y_m is None:
            raise ValueError(
                f"pitch_y_m is missing but rows = {self.rows} (needed to place rows apart); "
                "give the row spacing pitch_y_m in m"
            )
        if self.tractor_width_m > self.pitch_x_m:
            raise ValueError(
                f"tractor_width_m = {self.tractor_width_m!r} exceeds pitch_x_m = {self.pitch_x_m!r} "
                "(neighbouring tractors would overlap); give a footprint no wider than the pitch"
            )
        pitch_y = self.pitch_y_m if self.pitch_y_m is not None else np.inf
        if self.rows > 1 and self.tractor_length_m > pitch_y:
            raise ValueError(
                f"tractor_length_m = {self.tractor_length_m!r} exceeds pitch_y_m = {self.pitch_y_m!r} "
                "(neighbouring rows would overlap); give a footprint no longer than the row pitch"
            )
        return self

    # ----- derived geometry -------------------------------------------------------------
    @property
    def n_tractors(self) -> int:
        """Number of tractors, ``rows * columns``."""
        return self.rows * self.columns

    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, columns)``: the shape of per-tractor arrays."""
        return (self.rows, self.columns)

    @property
    def half_spacing_m(self) -> float:
        """Half the tractor spacing along x, ``d = pitch_x_m / 2`` (m), as in docs/theory.md 4a."""
        return self.pitch_x_m / 2.0

    @property
    def frame_period_s(self) -> float:
        """Time between two frames, ``1 / frame_rate_hz`` (s)."""
        return 1.0 / self.frame_rate_hz

    @property
    def tractor_x_m(self) -> np.ndarray:
        """Tractor centre x coordinates along one row, shape (columns,), m."""
        offsets = np.arange(self.columns) - (self.columns - 1) / 2.0
        return self.center_m[0] + offsets * self.pitch_x_m

    @property
    def tractor_y_m(self) -> np.ndarray:
        """Row centre y coordinates, shape (rows,), m."""
        offsets = np.arange(self.rows) - (self.rows - 1) / 2.0
        pitch = self.pitch_y_m if self.pitch_y_m is not None else 0.0
        return self.center_m[1] + offsets * pitch

    @property
    def tractor_positions_m(self) -> np.ndarray:
        """Tractor centres (x, y), shape (n_tractors, 2), m, row-major (row varies slowest)."""
        x, y = np.meshgrid(self.tractor_x_m, self.tractor_y_m)
        return np.column_stack([x.ravel(), y.ravel()])

    # ----- limits -----------------------------------------------------------------------
    def full_scale(self, kind: Literal["traction", "deflection"]) -> float:
        """The command limit for ``kind``: ``max_traction_pa`` (Pa) or ``max_deflection_m`` (m)."""
        if kind not in ("traction", "deflection"):
            raise ValueError(f"kind must be 'traction' or 'deflection', got {kind!r}; pick one of the two")
        limit = self.max_traction_pa if kind == "traction" else self.max_deflection_m
        if limit is None:
            field = "max_traction_pa" if kind == "traction" else "max_deflection_m"
            raise ValueError(
                f"kind = {kind!r} but display {self.display_id!r} has no {field}; "
                f"command the other quantity or give {field}"
            )
        return limit

    def check_commands(self, commands: np.ndarray,
                       kind: Literal["traction", "deflection"] = "traction") -> None:
        """Check a sequence of tractor commands against the per-tractor limits.

        Parameters
        ----------
        commands : array_like, shape (n_frames, rows, columns) or (n_frames, rows, columns, 2)
            Tractor tractions (Pa) or deflections (m) frame by frame; the trailing axis of
            length 2 holds the (x, y) parts and is allowed only when ``motion_axes == "xy"``.
        kind : {"traction", "deflection"}
            What the commands are.

        Raises
        ------
        ValueError
            Naming the first tractor and frame that breaks a limit (amplitude, slew rate,
            duty cycle), or a shape or finiteness problem.
        """
        full = self.full_scale(kind)
        unit = "Pa" if kind == "traction" else "m"
        c = np.asarray(commands, dtype=float)
        want = (self.rows, self.columns)
        ok_shape = c.ndim == 3 and c.shape[1:] == want
        if self.motion_axes == "xy":
            ok_shape = ok_shape or (c.ndim == 4 and c.shape[1:] == (*want, 2))
        if not ok_shape or c.shape[0] < 1:
            extra = " or (n_frames, rows, columns, 2)" if self.motion_axes == "xy" else ""
            raise ValueError(
                f"commands must have shape (n_frames, {self.rows}, {self.columns}){extra} for display "
                f"{self.display_id!r}, got {c.shape}; give one {self.rows} x {self.columns} frame per time step"
            )
        if not np.isfinite(c).all():
            raise ValueError("commands must be finite, got NaN or inf; replace them by numbers "
                             f"in {unit}")
        magnitude = np.linalg.norm(c, axis=-1) if c.ndim == 4 else np.abs(c)
        tol = 1e-12 * full
        over = magnitude > full + tol
        if over.any():
            f, r, k = (int(i) for i in np.argwhere(over)[0])
            raise ValueError(
                f"commands exceed the {kind} limit {full!r} {unit} at frame {f}, tractor (row {r}, "
                f"column {k}): {magnitude[f, r, k]!r} {unit}; scale the commands down"
            )
        if self.max_slew_rate_per_s is not None and c.shape[0] > 1:
            step = np.diff(c, axis=0)
            step = np.linalg.norm(step, axis=-1) if c.ndim == 4 else np.abs(step)
            rate = step * self.frame_rate_hz / full
            fast = rate > self.max_slew_rate_per_s * (1 + 1e-12)
            if fast.any():
                f, r, k = (int(i) for i in np.argwhere(fast)[0])
                raise ValueError(
                    f"commands change too fast between frames {f} and {f + 1} at tractor (row {r}, "
                    f"column {k}): {rate[f, r, k]!r} full scales per s > max_slew_rate_per_s "
                    f"{self.max_slew_rate_per_s!r}; smooth the commands or lower the speed"
                )
        duty = (magnitude > 0).mean(axis=0)
        busy = duty > self.max_duty_cycle + 1e-12
        if busy.any():
            r, k = (int(i) for i in np.argwhere(busy)[0])
            raise ValueError(
                f"tractor (row {r}, column {k}) is driven in {duty[r, k]:.3g} of the frames, more than "
                f"max_duty_cycle {self.max_duty_cycle!r}; leave it at rest in more frames"
            )

    # ----- presets ----------------------------------------------------------------------
    @classmethod
    def _preset(cls, overrides: dict, **values) -> DisplayDescription:
        """A preset: its layout ``values`` with the toolkit's nominal limits, then the user's ``overrides``."""
        return cls(**{**_NOMINAL_LIMITS, **values, **overrides})

    @classmethod
    def stress2(cls, **overrides) -> DisplayDescription:
        """The STReSS2 laterotactile display: 6 rows x 10 columns of tractors.

        The 6 x 10 layout is the one of Wang & Hayward, "Biomechanically optimized distributed
        tactile transducer based on lateral skin deformation", Int. J. Robotics Research 29
        (2010). The pitch 1.2 mm (x) x 1.4 mm (y), the footprint and the limits below are
        NOMINAL values chosen for this toolkit (not measured data): pass ``overrides`` to
        use a device's own numbers.
        """
        return cls._preset(
            overrides,
            display_id="STReSS2",
            rows=6,
            columns=10,
            pitch_x_m=1.2e-3,
            pitch_y_m=1.4e-3,
            tractor_width_m=0.6e-3,
            tractor_length_m=1.0e-3,
            description=("STReSS2 layout, 6 x 10 tractors (Wang & Hayward 2010); pitch 1.2 mm x "
                         "1.4 mm, footprint, limits and frame rate are nominal values"),
        )

    @classmethod
    def braille_row(cls, n_tractors: int = 10, pitch_x_m: float = 1.2e-3,
                    **overrides) -> DisplayDescription:
        """A one-row virtual Braille display: ``n_tractors`` tractors along x.

        A single row of laterally moving tractors driven as a travelling wave renders virtual
        Braille dots (the "virtual Braille display" of docs/theory.md 4a). Pitch, footprint
        and limits are NOMINAL values (the STReSS2 spacing along x); pass ``overrides`` to
        change any field.
        """
        return cls._preset(
            overrides,
            display_id="VirtualBrailleRow",
            rows=1,
            columns=n_tractors,
            pitch_x_m=pitch_x_m,
            tractor_width_m=pitch_x_m / 2.0,
            tractor_length_m=6e-3,
            description="one-row virtual Braille display; pitch, footprint and limits are nominal",
        )

    @classmethod
    def wh2008(cls, **overrides) -> DisplayDescription:
        """The row of 10 line tractors of Wang & Hayward (2008): centres at +-1, +-3, ..., +-9 mm.

        Five tractor pairs with half spacing d = 1 mm (pitch 2 mm along x), as in the tactile
        synthesis design of docs/theory.md section 4a (p = 4 d = 4 mm). The paper treats the
        tractors as line loads; a contact width is required here, so the footprint is the
        NOMINAL 1 mm (d, half the pitch) and the limits are the toolkit's nominal values (not
        from the paper): pass ``overrides`` to use a device's own numbers.
        """
        return cls._preset(
            overrides,
            display_id="WH2008",
            rows=1,
            columns=10,
            pitch_x_m=2e-3,
            tractor_width_m=1e-3,
            tractor_length_m=6e-3,
            description=("Wang & Hayward 2008 tractor row: 10 tractors at +-1, +-3, ..., +-9 mm (5 pairs, "
                         "d = 1 mm); footprint, limits and frame rate are nominal values"),
        )
