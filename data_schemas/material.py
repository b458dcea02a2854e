"""Skin material: elastic, viscoelastic (a Prony series) or layered; linear and isotropic.

Convention: ``young_modulus_pa`` is Young's modulus E in Pa (not the shear modulus, not the
plane-strain modulus); ``poisson_ratio`` is nu. Skin is nearly incompressible, so nu = 0.5 is
allowed exactly and is the default: code built on this record must treat it as a stable limit
(no division by 1 - 2 nu).

``model`` says how the modulus depends on time (docs/theory.md section 7):

- ``"elastic"`` (default): E at every time;
- ``"prony"``: ``young_modulus_pa`` is the relaxed modulus E_inf and ``terms`` the Prony terms
  ``(modulus_pa, relaxation_time_s)``: E(t) = E_inf + sum E_i exp(-t / tau_i);
- ``"sls"``: a standard linear solid, ``young_modulus_pa`` relaxed, ``instantaneous_modulus_pa``
  and ``relaxation_time_s``.

A ``layers`` list (top first; thickness, E, nu) on a ``base`` (``"rigid"``, bone, or an elastic
half-space table) describes a layered skin; ``young_modulus_pa`` and ``poisson_ratio`` are then the top
layer's (filled from it when omitted). In a scene file::

    [material]
    model = "prony"
    young_modulus = "0.2MPa"
    terms = [["1MPa", "4ms"], ["0.5MPa", "70ms"], ["0.3MPa", "1.4s"]]

    [material]                # a 4 mm pulp on bone
    layers = [{thickness = "4mm", young_modulus = "0.1MPa", poisson_ratio = 0.5}]
    base = "rigid"

    [material]                # a viscoelastic dermis on a viscoelastic pulp, on bone
    layers = [{thickness = "1mm", young_modulus = "0.4MPa", terms = [["0.8MPa", "10ms"]]},
              {thickness = "3mm", young_modulus = "0.2MPa", terms = [["1MPa", "4ms"], ["0.5MPa", "70ms"]]}]
"""

from __future__ import annotations

import warnings
from typing import Annotated, Literal

from pydantic import AfterValidator, model_validator

from tactilab.core import rules

from .base import Record, positive


def _poisson_ratio(nu: float) -> float:
    """nu in (-1, 0.5]: the ground floor's rule (:func:`tactilab.core.rules.poisson_ratio`), the solver's too."""
    return rules.poisson_ratio(nu, "poisson_ratio")


_Modulus = Annotated[float, positive("a stiffness", "give Young's modulus E in Pa, e.g. 1e6 for 1 MPa")]
_Nu = Annotated[float, AfterValidator(_poisson_ratio)]


class PronyTerm(Record):
    """One term ``E_i exp(-t / tau_i)`` of a relaxation modulus.

    Parameters
    ----------
    modulus_pa : float, Pa
        The term's spring modulus E_i, > 0.
    relaxation_time_s : float, s
        Its relaxation time tau_i, > 0 (fingertip skin: about 4 ms, 70 ms, 1.4 s).
    """

    modulus_pa: Annotated[float, positive("each Prony term needs a spring modulus", "e.g. \"1MPa\"")]
    relaxation_time_s: Annotated[float, positive("a relaxation time", "e.g. \"70ms\"")]


def _term_pairs(data: dict) -> dict:
    """Prony terms given as pairs ``["1MPa", "70ms"]`` become tables."""
    terms = data.get("terms")
    if isinstance(terms, list):
        data = dict(data)
        data["terms"] = [{"modulus": t[0], "relaxation_time": t[1]} if isinstance(t, list) and len(t) == 2 else t
                         for t in terms]
    return data


class SkinLayer(Record):
    """One layer: thickness (m), Young's modulus (Pa), Poisson's ratio, and optionally Prony terms.

    With ``terms`` the layer is viscoelastic (a Prony series, docs/theory.md section 7):
    ``young_modulus_pa`` is its relaxed modulus and each term ``(modulus_pa, relaxation_time_s)``
    adds ``E_i exp(-t / tau_i)``; Poisson's ratio stays constant in time.
    """

    thickness_m: Annotated[float, positive("a layer of zero thickness is no layer", "e.g. \"4mm\"")]
    young_modulus_pa: _Modulus
    poisson_ratio: _Nu = 0.5
    name: str = ""
    terms: tuple[PronyTerm, ...] = ()

    @classmethod
    def _edge_prepare(cls, data: dict, where: str) -> tuple[dict, dict[str, str]]:
        """File-edge hook: Prony terms may be pairs ``["1MPa", "70ms"]``."""
        return _term_pairs(data), {}

    @property
    def is_viscoelastic(self) -> bool:
        """True when the layer has Prony terms."""
        return bool(self.terms)


class ElasticBase(Record):
    """The elastic half-space under the layers: Young's modulus (Pa) and Poisson's ratio."""

    young_modulus_pa: _Modulus
    poisson_ratio: _Nu = 0.5


class SkinMaterial(Record):
    """Constants of the skin: elastic, viscoelastic or layered (see the module docstring).

    Parameters
    ----------
    young_modulus_pa : float, Pa
        Young's modulus E, > 0 (fingertip skin: about 1 to 4 MPa, docs/theory.md 4b); the relaxed
        modulus for ``"prony"`` and ``"sls"``; the top layer's with ``layers`` (filled from it).
    poisson_ratio : float
        Poisson's ratio nu in (-1, 0.5]; 0.5 (incompressible) is the default.
    name : str
        Free label, e.g. ``"fingertip"`` or ``"silicone phantom"``.
    model : {"elastic", "prony", "sls"}
        How the modulus depends on time.
    terms : tuple of PronyTerm
        The Prony terms of ``model = "prony"`` (at least one).
    instantaneous_modulus_pa, relaxation_time_s : float, optional
        The standard linear solid's glassy modulus (Pa, above the relaxed one) and relaxation time (s).
    layers : tuple of SkinLayer
        Layers, top first (``model = "elastic"`` only); a layer with Prony ``terms`` is viscoelastic.
    base : "rigid" or ElasticBase, optional
        What the last layer is bonded to (with ``layers``; default ``"rigid"``).
    """

    young_modulus_pa: _Modulus
    poisson_ratio: _Nu = 0.5
    name: str = ""
    model: Literal["elastic", "prony", "sls"] = "elastic"
    terms: tuple[PronyTerm, ...] = ()
    instantaneous_modulus_pa: Annotated[float, positive("a stiffness", "e.g. \"3MPa\"")] | None = None
    relaxation_time_s: Annotated[float, positive("a relaxation time", "e.g. \"70ms\"")] | None = None
    layers: tuple[SkinLayer, ...] = ()
    base: Literal["rigid"] | ElasticBase | None = None

    @classmethod
    def _edge_prepare(cls, data: dict, where: str) -> tuple[dict, dict[str, str]]:
        """File-edge hook: Prony terms may be pairs ``["1MPa", "70ms"]``."""
        return _term_pairs(data), {}

    @model_validator(mode="before")
    @classmethod
    def _top_layer_modulus(cls, data):
        """With layers, a missing modulus or Poisson's ratio is the top layer's."""
        if isinstance(data, dict) and data.get("layers"):
            top = data["layers"][0]
            for key in ("young_modulus_pa", "poisson_ratio"):
                value = top.get(key) if isinstance(top, dict) else getattr(top, key, None)
                if key not in data and value is not None:
                    data = {**data, key: value}
        return data

    @model_validator(mode="after")
    def _model_fields_agree(self) -> "SkinMaterial":
        sls = (self.instantaneous_modulus_pa, self.relaxation_time_s)
        if self.model == "prony" and not self.terms:
            raise ValueError("terms: model 'prony' needs at least one Prony term, e.g. terms = [[\"1MPa\", \"70ms\"]]; "
                             "or use model = 'elastic'")
        if self.model != "prony" and self.terms:
            raise ValueError(f"terms: only model 'prony' takes Prony terms, got model {self.model!r}; "
                             "set model = 'prony' or drop terms")
        if self.model == "sls":
            if None in sls:
                raise ValueError("instantaneous_modulus_pa, relaxation_time_s: model 'sls' needs both, e.g. "
                                 "instantaneous_modulus = \"3MPa\", relaxation_time = \"70ms\"")
            if not self.instantaneous_modulus_pa > self.young_modulus_pa:
                raise ValueError(f"instantaneous_modulus_pa: a standard linear solid stiffens on fast loading, so it "
                                 f"must exceed the relaxed young_modulus_pa = {self.young_modulus_pa!r}, got "
                                 f"{self.instantaneous_modulus_pa!r}; swap them, or use model = 'elastic'")
        elif sls != (None, None):
            raise ValueError(f"instantaneous_modulus_pa, relaxation_time_s: only model 'sls' takes them, got model "
                             f"{self.model!r}; set model = 'sls' or drop them")
        if self.layers and self.model != "elastic":
            raise ValueError(f"layers: a layered skin takes model 'elastic' (the default), got {self.model!r}; give a "
                             "viscous layer its own Prony terms, e.g. layers = [{thickness = \"4mm\", young_modulus = "
                             "\"0.2MPa\", terms = [[\"1MPa\", \"70ms\"]]}], and drop model")
        if self.base is not None and not self.layers:
            raise ValueError(f"base: is what the layers lie on, but there are no layers, got base {self.base!r}; "
                             "add layers or drop base")
        if self.layers and (self.young_modulus_pa, self.poisson_ratio) != (self.layers[0].young_modulus_pa,
                                                                           self.layers[0].poisson_ratio):
            top = self.layers[0]
            raise ValueError(f"young_modulus_pa, poisson_ratio: with layers they are the top layer's, "
                             f"({top.young_modulus_pa!r} Pa, {top.poisson_ratio!r}), got ({self.young_modulus_pa!r} Pa, "
                             f"{self.poisson_ratio!r}); drop them")
        return self

    @property
    def shear_modulus_pa(self) -> float:
        """Shear modulus G = E / (2 (1 + nu)), Pa."""
        return self.young_modulus_pa / (2.0 * (1.0 + self.poisson_ratio))

    @property
    def plane_strain_modulus_pa(self) -> float:
        """Plane-strain (contact) modulus E* = E / (1 - nu^2), Pa."""
        return self.young_modulus_pa / (1.0 - self.poisson_ratio**2)

    @property
    def is_incompressible(self) -> bool:
        """True when nu is exactly 0.5."""
        return self.poisson_ratio == 0.5

    @property
    def is_viscoelastic(self) -> bool:
        """True for ``model`` ``"prony"`` or ``"sls"``."""
        return self.model != "elastic"

    @property
    def has_viscoelastic_layers(self) -> bool:
        """True when a layer has Prony terms (a :class:`ViscoelasticLayeredHalfSpace` in forward)."""
        return any(layer.is_viscoelastic for layer in self.layers)

    @property
    def is_layered(self) -> bool:
        """True when the skin has layers."""
        return bool(self.layers)

    def half_space_constants(self, purpose: str) -> tuple[float, float]:
        """``(E in Pa, nu)`` for code that models the skin as one elastic half-space.

        Parameters
        ----------
        purpose : str
            What computes with them (named in the messages), e.g. ``"the biomimetic finger's scan"``.

        Raises
        ------
        ValueError
            For a layered material: one half-space cannot stand for its layers.

        Warns
        -----
        UserWarning
            For a viscoelastic material, which enters with its relaxed modulus (a quasi-static model).
        """
        if self.layers:
            raise ValueError(f"material: {purpose} models the skin as one elastic half-space, but the material has "
                             f"{len(self.layers)} layer(s); use an elastic or viscoelastic material there, and the "
                             "layered skin with tactilab.forward.skin_from_material (stress, contact, synthesis)")
        if self.model != "elastic":
            warnings.warn(f"material: {purpose} is quasi-static: the viscoelastic skin ({self.model}) enters with its "
                          f"relaxed modulus E_inf = {self.young_modulus_pa:g} Pa", UserWarning, stacklevel=2)
        return self.young_modulus_pa, self.poisson_ratio

    @property
    def prony_terms(self) -> tuple[tuple[float, float], ...]:
        """``((E_i in Pa, tau_i in s), ...)``: the Prony terms (one for ``"sls"``, none when elastic)."""
        if self.model == "sls":
            return ((self.instantaneous_modulus_pa - self.young_modulus_pa, self.relaxation_time_s),)
        return tuple((t.modulus_pa, t.relaxation_time_s) for t in self.terms)
