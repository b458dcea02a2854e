"""The scene given to a defect inversion must be the one that produced the recording.

:func:`check_scene_recording` compares the scene with what the recording file carries about the scene
that made it (:func:`tactilab.forward.scene_metadata.scene_mismatches`) and refuses a mismatch in one
line naming every field that differs; ``allow_mismatch`` (``tactilab invert --allow-scene-mismatch``)
turns the refusal into a warning, for real data whose metadata are known to differ from the model
scene. Parameters the inversion samples are not compared: their scene value is only a prior's centre.
"""

from __future__ import annotations

import warnings

__all__ = ["SAMPLED_FIELDS", "check_scene_recording"]

#: a sampled parameter -> the recorded fields its scene value sets (not compared when it is sampled)
SAMPLED_FIELDS = {"depth": ("depth_m",), "friction": ("friction",),
                  "young_modulus": ("young_modulus_pa", "contact_radius_m"),
                  "normal_force": ("normal_force_n", "contact_radius_m")}


def check_scene_recording(scene, path, *, sample=(), allow_mismatch: bool = False, name: str = "scene") -> list[str]:
    """Refuse ``scene`` unless it matches the scene recorded in the file ``path``.

    Parameters
    ----------
    scene : data_schemas Scene
        The scene the inversion will use.
    path : path
        The recording file (``.nc``, ``.parquet`` or ``.json``; a file that records no scene is
        compared on what it has: sampling rate, components, number of sensors).
    sample : sequence of str
        Parameters the inversion samples (names of :data:`SAMPLED_FIELDS`).
    allow_mismatch : bool
        Warn (``UserWarning``) instead of raising, for real data whose metadata differ.
    name : str
        How the caller names the scene (for the message).

    Returns
    -------
    list of str
        The fields that differ (empty when they match).

    Raises
    ------
    ValueError
        On a mismatch, unless ``allow_mismatch``.
    """
    from tactilab.data_schemas.recording_metadata import scene_fields
    from tactilab.forward.scene_metadata import scene_mismatches

    ignore = [field for s in sample for field in SAMPLED_FIELDS.get(s, ())]
    differ = scene_mismatches(scene, scene_fields(path), ignore)
    if differ:
        text = f"the scene did not produce the recording {path}: " + "; ".join(differ)
        if not allow_mismatch:
            raise ValueError(f"{name}: {text}; give the scene that produced it, or allow the mismatch "
                             "(--allow-scene-mismatch) for real data whose metadata differ")
        warnings.warn(f"{name}: {text}; inverting with the scene's values as asked (scene mismatch allowed)",
                      UserWarning, stacklevel=2)
    return differ
