"""The skin model a material record describes: elastic, viscoelastic or layered.

:func:`skin_from_material` turns a :class:`tactilab.data_schemas.SkinMaterial` (a scene's
``[material]`` table, a ``--material`` file) into the physics object that computes with it:
a :class:`HalfSpace` for ``model = "elastic"``, a :class:`ViscoelasticHalfSpace` for ``"prony"``
and ``"sls"``, and a :class:`LayeredHalfSpace` when the material has layers.
"""

from __future__ import annotations

from ..halfspace import HalfSpace
from .layered import Layer, LayeredHalfSpace
from .prony import Prony
from .viscoelastic import ViscoelasticHalfSpace


def skin_from_material(material):
    """The skin model of a material record.

    Parameters
    ----------
    material : SkinMaterial
        A validated record (SI units).

    Returns
    -------
    HalfSpace, ViscoelasticHalfSpace or LayeredHalfSpace
    """
    if not all(hasattr(material, key) for key in ("young_modulus_pa", "poisson_ratio", "model", "layers")):
        raise ValueError(f"material: expected a SkinMaterial record, got {type(material).__name__}; read one with "
                         "tactilab.data_schemas.read_material(path)")
    if material.layers:
        layers = [Layer(layer.thickness_m, layer.young_modulus_pa, layer.poisson_ratio) for layer in material.layers]
        base = material.base
        if base is None or base == "rigid":
            return LayeredHalfSpace(layers, base="rigid")
        return LayeredHalfSpace(layers, base=HalfSpace(base.young_modulus_pa, base.poisson_ratio))
    if material.model == "elastic":
        return HalfSpace.from_material(material)
    return ViscoelasticHalfSpace(Prony(material.young_modulus_pa, material.prony_terms), material.poisson_ratio)
