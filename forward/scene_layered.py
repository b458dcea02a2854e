"""A finger scene on a layered skin: the skin, the size of its grid, the texture's full-contact pressure.

Used by :class:`.scene_frames.SceneFrames` when the scene's ``[material]`` has ``layers`` (docs/scenes.md,
"Layered skin"): the contact is solved on the :class:`tactilab.forward.skin.LayeredHalfSpace` (models
``"exact"`` and ``"linear"``; ``"modulation"`` is a half-space formula and is refused), and the sensors
read through its transfer (:class:`.scene_readout.SensorReadout`). SI units.
"""

from __future__ import annotations

import numpy as np

from .skin import skin_from_material


def refuse_layered_modulation(model: str) -> None:
    """The one refusal of the modulation model on a layered skin (its M = 1 + h / h_ref scales the
    half-space's Hertz traction, docs/theory.md 4b)."""
    if model == "modulation":
        raise ValueError("contact.model: 'modulation' scales the Hertz traction of a homogeneous half-space "
                         "(docs/theory.md 4b), but the scene's material has layers; use model = 'exact', 'linear' or "
                         "'auto' (which picks between them) for a layered skin")


def layered_skin(scene):
    """The elastic :class:`LayeredHalfSpace` of a finger scene's layered material, or a clear refusal."""
    m = scene.material
    if m.has_viscoelastic_layers:
        raise ValueError("material.layers: a scene simulation takes elastic layers (a quasi-static scan), but a layer "
                         "has Prony terms; give each layer its relaxed young_modulus without terms, or solve the "
                         "viscoelastic layers with the stress, contact and synthesis commands")
    if scene.contact.periodic:
        raise ValueError("contact.mean_pressure: a periodic cell takes a homogeneous half-space, but the scene's "
                         "material has layers; press a finger (normal_force, finger_radius) on the layered skin, "
                         "or drop the layers")
    return skin_from_material(m)


def softest(material) -> tuple[float, float]:
    """``(E in Pa, nu)`` of the most compliant (smallest E / (1 - nu^2)) material of a layered skin, its
    base included: a Hertz contact on it is at least as wide as the layered contact, so it sizes the grid."""
    parts = [(layer.young_modulus_pa, layer.poisson_ratio) for layer in material.layers]
    if material.base is not None and material.base != "rigid":
        parts.append((material.base.young_modulus_pa, material.base.poisson_ratio))
    return min(parts, key=lambda e: e[0] / (1 - e[1] ** 2))


def layered_deflection_pressure(skin, h: np.ndarray, spacing) -> np.ndarray:
    """The zero-mean surface pressure (Pa) that imposes the deflection ``h`` (m) on a periodic grid of a
    layered skin: ``h~ / C_zz(k)`` per wavenumber (``E* |k| H~ / 2`` on a half-space)."""
    axes = tuple(range(-h.ndim, 0))
    kx = 2 * np.pi * np.fft.rfftfreq(h.shape[-1], spacing[0])
    if h.ndim == 1:
        c = skin.surface_compliance(kx, None)[..., 0, 0].real
    else:
        ky = 2 * np.pi * np.fft.fftfreq(h.shape[0], spacing[1])
        c = skin.surface_compliance(kx[None, :], ky[:, None])[..., 0, 0].real
    spectrum = np.fft.rfftn(h, axes=axes)
    c.flat[0] = np.inf  # the mean pressure is the finger's, not the texture's
    return np.fft.irfftn(spectrum / c, s=h.shape, axes=axes)


def describe_layers(material) -> str:
    """The layers of a material in words, mm and kPa, top first, and what they lie on."""
    stack = ", ".join(f"{layer.thickness_m * 1e3:g} mm of E = {layer.young_modulus_pa / 1e3:g} kPa, "
                      f"nu = {layer.poisson_ratio:g}" for layer in material.layers)
    base = material.base
    on = "a rigid base" if base is None or base == "rigid" else \
        f"a half-space of E = {base.young_modulus_pa / 1e3:g} kPa, nu = {base.poisson_ratio:g}"
    return f"{stack} on {on}"
