"""The skin model a material record describes: elastic, viscoelastic or layered.

:func:`skin_from_material` turns a :class:`tactilab.data_schemas.SkinMaterial` (a scene's
``[material]`` table, a ``--material`` file) into the physics object that computes with it:
a :class:`HalfSpace` for ``model = "elastic"``, a :class:`ViscoelasticHalfSpace` for ``"prony"``
and ``"sls"``, a :class:`LayeredHalfSpace` when the material has layers, and a
:class:`ViscoelasticLayeredHalfSpace` when a layer has Prony terms.
"""

from __future__ import annotations

from ..halfspace import HalfSpace
from .layered import Layer, LayeredHalfSpace
from .layered_viscoelastic import ViscoelasticLayeredHalfSpace
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
    HalfSpace, ViscoelasticHalfSpace, LayeredHalfSpace or ViscoelasticLayeredHalfSpace
    """
    if not all(hasattr(material, key) for key in ("young_modulus_pa", "poisson_ratio", "model", "layers")):
        raise ValueError(f"material: expected a SkinMaterial record, got {type(material).__name__}; read one with "
                         "tactilab.data_schemas.read_material(path)")
    if material.layers:
        layers = [Layer(layer.thickness_m, Prony(layer.young_modulus_pa, [(t.modulus_pa, t.relaxation_time_s)
                                                                           for t in layer.terms])
                        if layer.terms else layer.young_modulus_pa, layer.poisson_ratio) for layer in material.layers]
        base = material.base
        base = "rigid" if base is None or base == "rigid" else HalfSpace(base.young_modulus_pa, base.poisson_ratio)
        if any(layer.is_viscoelastic for layer in layers):
            return ViscoelasticLayeredHalfSpace(layers, base=base)
        return LayeredHalfSpace(layers, base=base)
    if material.model == "elastic":
        return HalfSpace.from_material(material)
    return ViscoelasticHalfSpace(Prony(material.young_modulus_pa, material.prony_terms), material.poisson_ratio)
