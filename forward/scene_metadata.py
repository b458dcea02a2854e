"""A scene and the recording it made: what ``simulate`` writes about the scene (the recording's metadata), and the
check that a scene given to ``invert`` is the one that produced the recording.

:func:`recording_attrs` is the one list of the scene's scalar parameters a recording carries (SI, the
unit in each name); :func:`scene_mismatches` compares a scene with what a recording file carries
(:func:`tactilab.data_schemas.recording_metadata.scene_fields`): every field both describe,
scalars, the sensors' positions, the contact path and the components, so a field a writer adds is
compared once the scene describes it too. A scene that did not produce the recording gives an
inversion that is confidently wrong (a contact radius 2x off put a profile peak 7x too high and 1.15 mm
off), so ``tactilab invert`` refuses it unless told the metadata are known to differ.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["RTOL", "recording_attrs", "scene_description", "scene_mismatches"]

#: relative tolerance of the comparison: far above the files' rounding, far below a real difference
RTOL = 1e-6

#: attributes that describe the numerics of a simulation, not the scene (never compared)
NUMERICS = ("grid_spacing_m",)

#: how each field is shown in a message: (label, unit, factor from SI)
_SHOW = {"depth_m": ("sensor depth", "mm", 1e3), "contact_radius_m": ("contact radius", "mm", 1e3),
         "normal_force_n": ("normal force", "N", 1.0), "young_modulus_pa": ("Young's modulus", "kPa", 1e-3),
         "sampling_rate_hz": ("sampling rate", "Hz", 1.0), "sensor_positions_m": ("sensor positions", "mm", 1e3),
         "contact_x_m": ("contact path", "mm", 1e3)}


def recording_attrs(finger) -> dict[str, float]:
    """The scalar scene parameters a finger scene's recording carries (SI, unit in the name).

    Parameters
    ----------
    finger : BiomimeticFinger
        The simulated finger.
    """
    c = finger.contact
    return dict(depth_m=finger.depth, contact_radius_m=c.contact_radius, normal_force_n=c.normal_force,
                friction=finger.friction, adhesion=finger.adhesion, grid_spacing_m=finger.spacing,
                young_modulus_pa=c.young_modulus, poisson_ratio=c.poisson_ratio)


def scene_description(scene) -> dict[str, Any]:
    """What a recording of ``scene`` carries about it, in the form of ``recording_metadata.scene_fields``."""
    s = scene.scan
    out: dict[str, Any] = dict(depth_m=float(scene.sensors.depth_m), young_modulus_pa=scene.material.young_modulus_pa,
                               poisson_ratio=scene.material.poisson_ratio, sampling_rate_hz=s.sampling_rate_hz,
                               components=tuple(scene.sensors.components), n_sensors=scene.sensors.n_sensors,
                               sensor_positions_m=np.asarray(scene.sensors.positions_m, dtype=float),
                               contact_x_m=np.asarray(s.positions_m, dtype=float))
    if scene.contact is not None and scene.display is None and not scene.contact.periodic:  # a finger
        from .finger import BiomimeticFinger

        out.update({k: v for k, v in recording_attrs(BiomimeticFinger.from_scene(scene)).items() if k not in NUMERICS})
    return out


def scene_mismatches(scene, recorded: dict[str, Any], ignore=()) -> list[str]:
    """What differs between ``scene`` and a recording's metadata, one phrase per field (empty: they match).

    Parameters
    ----------
    scene : data_schemas Scene
    recorded : dict
        ``recording_metadata.scene_fields(path)``.
    ignore : iterable of str
        Fields not to compare (e.g. the parameters an inversion samples, whose scene value is only a
        prior's centre).
    """
    expected = scene_description(scene)
    skip = set(ignore) | set(NUMERICS)
    out = []
    for key, want in expected.items():
        if key in skip or key not in recorded:
            continue
        got = recorded[key]
        if isinstance(want, tuple):
            if tuple(want) != tuple(got):
                out.append(f"{key}: scene {', '.join(want)}, recording {', '.join(map(str, got))}")
            continue
        if isinstance(want, str):
            if want != str(got):
                out.append(f"{key}: scene {want!r}, recording {got!r}")
            continue
        a, b = np.asarray(want, dtype=float), np.asarray(got, dtype=float)
        label, unit, factor = _SHOW.get(key, (key, "", 1.0))
        if a.shape != b.shape:
            out.append(f"{label}: scene has {a.size} values, recording {b.size}")
        elif not np.allclose(a, b, rtol=RTOL, atol=RTOL * float(np.max(np.abs(a), initial=0.0))):
            if a.ndim == 0:
                out.append(f"{label}: scene {float(a) * factor:.6g}{' ' + unit if unit else ''}, recording "
                           f"{float(b) * factor:.6g}{' ' + unit if unit else ''}")
            else:
                i = np.unravel_index(int(np.argmax(np.abs(a - b))), a.shape)
                out.append(f"{label}: scene {a[i] * factor:.6g} {unit}, recording {b[i] * factor:.6g} {unit} at "
                           f"index {i if a.ndim > 1 else i[0]}")
    return out
