"""One table of input rules, run against every public entry point that takes the quantity.

``RULES`` holds, per quantity, values every entry point must accept, values it must refuse and
the words of the refusal (the rule lives once, in ``core/rules.py``). ``ENTRY_POINTS`` calls each
public function, class or method with one argument set to a value from the table and everything
else valid. ``test_every_rule_parameter_of_every_face_is_in_the_table`` walks the faces and fails
when a parameter named like a quantity is missing, so a new entry point cannot bring its own
rule. Issue 22 made two rules less strict: sensor records accept the shear aliases ('xz') and
Poisson's ratio is (-1, 0.5] everywhere; each has its own test here.
"""

from __future__ import annotations

import importlib
import inspect
import math
import re
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import pytest

import tactilab.forward as fwd
import tactilab.forward.skin as fskin
import tactilab.inversion as inv
from tactilab.core import rules
from tactilab.data_schemas import (ElasticBase, Recording, SensorArray, SkinLayer, SkinMaterial, load_example,
                                  random_rough_surface, read_height_map)


class Rule(NamedTuple):
    good: tuple
    bad: tuple
    message: str  # a regex every refusal of a bad value matches


NAN, INF = math.nan, math.inf
RULES = {
    "depth": Rule((1e-3, 2.5e-4), (0.0, -1e-3, NAN, INF), r"finite and > 0 m"),
    "spacing": Rule((1e-4, 2.5e-5), (0.0, -1e-4, NAN, INF), r"finite and > 0 m"),
    "young_modulus": Rule((1e6, 2.5e3), (0.0, -1e6, NAN, INF), r"finite and > 0 Pa"),
    "poisson_ratio": Rule((0.5, 0.3, 0.0, -0.5), (0.6, 0.5000001, -1.0, -1.5, NAN), r"\(-1, 0\.5\]"),
    "components": Rule((("zz",), ("xz", "zz"), rules.COMPONENTS),
                       (("qq",), ("zz", "pressure")), r"unknown component"),
}
#: parameter name -> quantity of the table
QUANTITY = {"depth": "depth", "spacing": "spacing", "E": "young_modulus", "young_modulus": "young_modulus",
            "nu": "poisson_ratio", "poisson_ratio": "poisson_ratio", "components": "components"}

# ----------------------------------------------------------------------------- cheap valid inputs
N = 8
H = 1e-4
HS = fwd.HalfSpace(1e6, 0.5)
LAYERED = fwd.LayeredHalfSpace([fwd.Layer(2e-3, 1e6, 0.5)], base=HS)  # deep enough for every good depth
LOAD = fwd.SurfaceLoad(p=1e3 * np.cos(2 * np.pi * np.arange(N) / N)[None, :].repeat(N, 0), spacing=H, periodic=True)
SCENE = load_example("tractor_display")
DISPLAY = SCENE.display
X = np.linspace(-2e-3, 2e-3, 5)
#: a tractor design per good depth (a design holds the depth it was made for); bad depths use the first
DESIGNS = {d: fwd.optimal_half_spacing(d, grid_points=20) for d in (1e-3, 2.5e-4)}
ROW = np.zeros(DISPLAY.tractor_x_m.shape[-1])  # one line load per tractor of a row, N/m
CONTACT = fwd.HertzContact(0.5, finger_radius=0.01, young_modulus=1e6)
SLS = fwd.Prony.sls(1e6, 3e6, 0.07)
VS = fwd.ViscoelasticHalfSpace(SLS)
VLAYERED = fwd.ViscoelasticLayeredHalfSpace([fwd.Layer(2e-3, SLS, 0.5)], base=VS)  # any depth lies in it
_HEIGHT_MAP: list = []
_HISTORY: list = []


def _viscoelastic_history():
    """A small solved viscoelastic contact (two steps), once per session."""
    if not _HISTORY:
        _HISTORY.append(fwd.solve_viscoelastic_contact(VS, np.linspace(-1, 1, 32) ** 2 * 1e-5, 2.5e-5, [0.0, 0.1],
                                                       normal_force=1.0))
    return _HISTORY[0]


def _height_map_file():
    """A small .npy height map (um), written once per session in a temporary folder."""
    if not _HEIGHT_MAP:
        import atexit
        import pathlib
        import shutil
        import tempfile

        folder = pathlib.Path(tempfile.mkdtemp(prefix="tactilab-rules-"))
        atexit.register(shutil.rmtree, folder, ignore_errors=True)
        np.save(folder / "h.npy", np.zeros((N, N)))
        _HEIGHT_MAP.append(folder / "h.npy")
    return _HEIGHT_MAP[0]


def _height(x, y=None):
    return 1e-6 * np.cos(2 * np.pi * np.asarray(x) / (N * H))


def _traction(x, y=None):
    return 1e3 * np.cos(2 * np.pi * np.asarray(x) / (N * H))


def _design(depth):
    return DESIGNS.get(depth, DESIGNS[1e-3])


def _kernel_spectrum(spacing=(H,), depth=1e-3, nu=0.5):
    return fwd.halfspace.dcfft_kernel_spectrum((N,), spacing, depth, nu, np.eye(6)[[2]], ("z",))


def _recording(components):
    return Recording(values=np.zeros((2, 1, len(components))), sampling_rate_hz=100.0, sensor_ids=("a",),
                     components=components)


def _from_dataframe(components):
    try:  # the table's good values make their own table; a bad one is tried on a valid table
        names = rules.components(components)
    except ValueError:
        names = ("zz",)
    return Recording.from_dataframe(_recording(names).to_dataframe(), components=components)


def _posterior():
    op = inv.halfspace_fourier_operator((N,), H, 1e-3)
    return inv.gaussian_posterior(op, np.zeros(N), inv.StationaryPrior(variance=1.0), 1e-3, spacing=H)


# (public name, parameter) -> call with the value; the public name is the one users import
def _cell_scan(**kwargs):
    """A one-frame periodic plane-strain cell of the surface inversion's forward map."""
    args = dict(young_modulus=1e6, poisson_ratio=0.5, grid_shape=(N,), spacing=H, shape_gap=np.zeros(N),
                positions=[0.0], weights_p=np.ones((N, 1)), weights_q=np.zeros((N, 1)),
                profile=inv.ProfileGrid(x=np.arange(N) * H, periodic=True), mean_pressure=1e3, periodic=True)
    return inv.ContactScan(**{**args, **kwargs})


_CELL = {}


def _surface_cell():
    """A periodic cell scene (a 0.6 mm grating at 5 kPa, two frames) and its exact-model recording."""
    if not _CELL:
        from tactilab.data_schemas import Scene
        from tactilab.data_schemas.base import record_from_dict
        from tactilab.forward.scene_models import scene_signals

        scene = record_from_dict(Scene, {
            "material": {"young_modulus": "1MPa", "poisson_ratio": 0.5},
            "surface": {"kind": "sinusoidal_grating", "period": "0.6mm", "amplitude": "1um"},
            "contact": {"mean_pressure": "5kPa", "model": "exact"},
            "sensors": {"quantity": "stress", "components": ["zz"], "depth": "0.3mm", "noise_std": 10.0,
                        "positions_m": [[0.0, 0.0], [1e-4, 0.0]]},
            "scan": {"speed": "25mm/s", "duration": "2ms", "sampling_rate": "1kHz"}})
        values, _ = scene_signals(scene, "exact", grid_spacing=2.5e-5)
        _CELL["cell"] = (scene, Recording.from_sensors(scene.sensors, values, 1e3))
    return _CELL["cell"]


ENTRY_POINTS: dict[tuple[str, str], Callable] = {
    # the rules themselves
    ("core.rules.depth", "value"): lambda v: rules.depth(v),
    ("core.rules.depths", "value"): lambda v: rules.depths([1e-3, v]),
    ("core.rules.spacing", "value"): lambda v: rules.spacing(v, 2),
    ("core.rules.young_modulus", "value"): lambda v: rules.young_modulus(v),
    ("core.rules.poisson_ratio", "value"): lambda v: rules.poisson_ratio(v),
    ("core.rules.components", "value"): lambda v: rules.components(v),
    # records
    ("data_schemas.SkinMaterial", "poisson_ratio"): lambda v: SkinMaterial(young_modulus_pa=1e6, poisson_ratio=v),
    ("data_schemas.SkinLayer", "poisson_ratio"): lambda v: SkinLayer(thickness_m=1e-3, young_modulus_pa=1e5,
                                                                     poisson_ratio=v),
    ("data_schemas.ElasticBase", "poisson_ratio"): lambda v: ElasticBase(young_modulus_pa=1e6, poisson_ratio=v),
    ("data_schemas.SensorArray", "components"): lambda v: SensorArray(positions_m=[[0, 0]], depth_m=1e-3, components=v),
    ("data_schemas.Recording", "components"): _recording,
    ("data_schemas.Recording.from_dataframe", "components"): _from_dataframe,
    # the solver
    ("forward.HalfSpace", "E"): lambda v: fwd.HalfSpace(v),
    ("forward.HalfSpace", "nu"): lambda v: fwd.HalfSpace(1e6, v),
    ("forward.HalfSpace.stress", "depth"): lambda v: HS.stress(LOAD, v, components=("zz",)),
    ("forward.HalfSpace.stress", "components"): lambda v: HS.stress(LOAD, 1e-3, components=v),
    ("forward.HalfSpace.strain", "depth"): lambda v: HS.strain(LOAD, v, components=("zz",)),
    ("forward.HalfSpace.strain", "components"): lambda v: HS.strain(LOAD, 1e-3, components=v),
    ("forward.HalfSpace.pressure_from_deflection", "spacing"): lambda v: HS.pressure_from_deflection(np.zeros(N), v),
    ("forward.HalfSpace.operator", "spacing"): lambda v: HS.operator((N,), v),
    ("forward.HalfSpace.operator", "depth"): lambda v: HS.operator((N,), H, depth=v),
    ("forward.HalfSpace.operator", "components"): lambda v: HS.operator((N,), H, components=v),
    ("forward.LoadToSensor", "spacing"): lambda v: fwd.LoadToSensor(HS, (N,), v),
    ("forward.LoadToSensor", "depth"): lambda v: fwd.LoadToSensor(HS, (N,), H, depth=v),
    ("forward.LoadToSensor", "components"): lambda v: fwd.LoadToSensor(HS, (N,), H, components=v),
    ("forward.SurfaceLoad", "spacing"): lambda v: fwd.SurfaceLoad(p=np.zeros(N), spacing=v),
    ("forward.TractionField", "spacing"): lambda v: fwd.TractionField(p=_traction, shape=N, spacing=v),
    ("forward.TractionField.sample", "spacing"): (
        lambda v: fwd.TractionField(p=_traction, shape=N, spacing=H).sample(N, v)),
    ("forward.DeflectionLoad", "young_modulus"): lambda v: fwd.DeflectionLoad(_height, v, 0.5, shape=N, spacing=H),
    ("forward.DeflectionLoad", "nu"): lambda v: fwd.DeflectionLoad(_height, 1e6, v, shape=N, spacing=H),
    ("forward.DeflectionLoad", "spacing"): lambda v: fwd.DeflectionLoad(_height, 1e6, 0.5, shape=N, spacing=v),
    ("forward.DeflectionLoad.sample", "spacing"): (
        lambda v: fwd.DeflectionLoad(_height, 1e6, 0.5, shape=N, spacing=H).sample(N, v)),
    ("forward.HertzContact", "young_modulus"): lambda v: fwd.HertzContact(0.5, young_modulus=v),
    ("forward.HertzContact", "poisson_ratio"): lambda v: fwd.HertzContact(0.5, poisson_ratio=v),
    ("forward.HertzContact.load", "spacing"): lambda v: CONTACT.load(spacing=v),
    ("experiments.modelling.FingerContact", "young_modulus"): (
        lambda v: importlib.import_module("tactilab.experiments.modelling").FingerContact(young_modulus=v)),
    ("experiments.modelling.FingerContact", "poisson_ratio"): (
        lambda v: importlib.import_module("tactilab.experiments.modelling").FingerContact(poisson_ratio=v)),
    ("forward.ContactLoad", "spacing"): lambda v: fwd.ContactLoad(CONTACT, spacing=v),
    ("data_schemas.random_rough_surface", "spacing"): lambda v: random_rough_surface((N, N), v, rms_height=1e-6,
                                                                                     rng=np.random.default_rng(0)),
    ("forward.random_rough_surface", "spacing"): lambda v: fwd.random_rough_surface((N,), v, rms_height=1e-6,
                                                                                    rng=np.random.default_rng(0)),
    ("data_schemas.read_height_map", "spacing"): lambda v: read_height_map(_height_map_file(), spacing=v,
                                                                           height_unit="um"),
    ("forward.ContactCompliance", "spacing"): lambda v: fwd.ContactCompliance(HS, (N, N), v, periodic=True),
    ("forward.solve_contact", "spacing"): lambda v: fwd.solve_contact(HS, np.linspace(-1, 1, N) ** 2 * 1e-6, v,
                                                                      normal_force=1.0),
    ("forward.WestergaardContact", "E"): lambda v: fwd.WestergaardContact(1e-6, 1e-3, 1e3, v),
    ("forward.WestergaardContact", "nu"): lambda v: fwd.WestergaardContact(1e-6, 1e-3, 1e3, 1e6, nu=v),
    ("forward.harmonic_field", "depth"): lambda v: fwd.harmonic_field([1e3, 1e3], 1e-3, X, v, 1e6),
    ("forward.harmonic_field", "E"): lambda v: fwd.harmonic_field([1e3, 1e3], 1e-3, X, 1e-3, v),
    ("forward.harmonic_field", "nu"): lambda v: fwd.harmonic_field([1e3, 1e3], 1e-3, X, 1e-3, 1e6, nu=v),
    ("forward.harmonic_field", "components"): (
        lambda v: fwd.harmonic_field([1e3, 1e3], 1e-3, X, 1e-3, 1e6, components=v)),
    ("forward.interface_model_errors", "spacing"): lambda v: fwd.interface_model_errors(np.zeros(N), v, 1e3, 1e6),
    ("forward.interface_model_errors", "E"): lambda v: fwd.interface_model_errors(np.zeros(N), H, 1e3, v),
    ("forward.interface_model_errors", "nu"): lambda v: fwd.interface_model_errors(np.zeros(N), H, 1e3, 1e6, nu=v),
    ("forward.interface_model_errors", "depth"): (
        lambda v: fwd.interface_model_errors(np.zeros(N), H, 1e3, 1e6, depth=v)),
    ("forward.interface_model_errors", "components"): (
        lambda v: fwd.interface_model_errors(np.zeros(N), H, 1e3, 1e6, components=v)),
    ("forward.linear_pressure", "spacing"): lambda v: fwd.linear_pressure(np.zeros(N), v, 1e3, 1e6),
    ("forward.linear_pressure", "E"): lambda v: fwd.linear_pressure(np.zeros(N), H, 1e3, v),
    ("forward.linear_pressure", "nu"): lambda v: fwd.linear_pressure(np.zeros(N), H, 1e3, 1e6, nu=v),
    ("forward.full_contact_pressure", "spacing"): lambda v: fwd.full_contact_pressure(np.zeros(N), v, 1e6),
    ("forward.full_contact_pressure", "E"): lambda v: fwd.full_contact_pressure(np.zeros(N), H, v),
    ("forward.full_contact_pressure", "nu"): lambda v: fwd.full_contact_pressure(np.zeros(N), H, 1e6, nu=v),
    ("forward.HalfSpace.surface_influence", "spacing"): lambda v: HS.surface_influence(X, X, v),
    # the viscoelastic skin (forward.skin)
    ("forward.ViscoelasticHalfSpace", "nu"): lambda v: fwd.ViscoelasticHalfSpace(SLS, v),
    ("forward.ViscoelasticHalfSpace.stress", "depth"): lambda v: VS.stress(LOAD, v, [0.0], components=("zz",)),
    ("forward.ViscoelasticHalfSpace.stress", "components"): lambda v: VS.stress(LOAD, 1e-3, [0.0], components=v),
    ("forward.ViscoelasticHalfSpace.strain", "depth"): lambda v: VS.strain(LOAD, v, [0.0], components=("zz",)),
    ("forward.ViscoelasticHalfSpace.strain", "components"): lambda v: VS.strain(LOAD, 1e-3, [0.0], components=v),
    ("forward.ViscoelasticHalfSpace.pressure_from_deflection", "spacing"):
        lambda v: VS.pressure_from_deflection(np.zeros(N), v, [0.0]),
    ("forward.ViscoelasticHalfSpace.stress_from_deflection", "spacing"):
        lambda v: VS.stress_from_deflection(np.zeros(N), v, 1e-3, [0.0], components=("zz",)),
    ("forward.ViscoelasticHalfSpace.stress_from_deflection", "depth"):
        lambda v: VS.stress_from_deflection(np.zeros(N), H, v, [0.0], components=("zz",)),
    ("forward.ViscoelasticHalfSpace.stress_from_deflection", "components"):
        lambda v: VS.stress_from_deflection(np.zeros(N), H, 1e-3, [0.0], components=v),
    ("forward.ViscoelasticHalfSpace.strain_from_deflection", "spacing"):
        lambda v: VS.strain_from_deflection(np.zeros(N), v, 1e-3, [0.0], components=("zz",)),
    ("forward.ViscoelasticHalfSpace.strain_from_deflection", "depth"):
        lambda v: VS.strain_from_deflection(np.zeros(N), H, v, [0.0], components=("zz",)),
    ("forward.ViscoelasticHalfSpace.strain_from_deflection", "components"):
        lambda v: VS.strain_from_deflection(np.zeros(N), H, 1e-3, [0.0], components=v),
    ("forward.ViscoelasticHalfSpace.sliding_pressure", "spacing"): lambda v: VS.sliding_pressure(np.zeros(N), v, 0.1),
    ("forward.ViscoelasticHalfSpace.steady_sliding", "spacing"):
        lambda v: VS.steady_sliding(np.zeros(N), v, 0.1, 1e-3, components=("zz",)),
    ("forward.ViscoelasticHalfSpace.steady_sliding", "depth"):
        lambda v: VS.steady_sliding(np.zeros(N), H, 0.1, v, components=("zz",)),
    ("forward.ViscoelasticHalfSpace.steady_sliding", "components"):
        lambda v: VS.steady_sliding(np.zeros(N), H, 0.1, 1e-3, components=v),
    ("forward.ViscoelasticHalfSpace.surface_influence", "spacing"): lambda v: VS.surface_influence(X, X, v),
    ("forward.ViscoelasticHalfSpace.operator", "spacing"): lambda v: VS.operator((N,), v, [0.0]),
    ("forward.ViscoelasticHalfSpace.operator", "depth"): lambda v: VS.operator((N,), H, [0.0], depth=v),
    ("forward.ViscoelasticHalfSpace.operator", "components"): lambda v: VS.operator((N,), H, [0.0], components=v),
    ("forward.Prony.shear_relaxation_modulus", "nu"): lambda v: SLS.shear_relaxation_modulus(0.1, v),
    ("forward.Prony.shear_creep_compliance", "nu"): lambda v: SLS.shear_creep_compliance(0.1, v),
    ("forward.solve_viscoelastic_contact", "spacing"):
        lambda v: fwd.solve_viscoelastic_contact(VS, np.linspace(-1, 1, N) ** 2 * 1e-6, v, [0.0, 0.1],
                                                 normal_force=1.0),
    ("forward.skin.HistoryOperator", "spacing"): lambda v: fskin.HistoryOperator(VS, (N,), v, [0.0, 0.1], [0.0]),
    ("forward.skin.HistoryOperator", "depth"): lambda v: fskin.HistoryOperator(VS, (N,), H, [0.0, 0.1], [0.0], depth=v),
    ("forward.skin.HistoryOperator", "components"):
        lambda v: fskin.HistoryOperator(VS, (N,), H, [0.0, 0.1], [0.0], components=v),
    ("forward.skin.ViscoelasticContactHistory.strain", "depth"):
        lambda v: _viscoelastic_history().strain(VS, v, components=("zz",)),
    ("forward.skin.ViscoelasticContactHistory.strain", "components"):
        lambda v: _viscoelastic_history().strain(VS, 1e-3, components=v),
    ("forward.ContactLoad.sample", "spacing"): lambda v: fwd.ContactLoad(CONTACT, spacing=H).sample((N, N), v),
    ("forward.angular_wavenumbers", "spacing"): lambda v: fwd.angular_wavenumbers((N, N), v),
    ("forward.finger_gap", "spacing"): lambda v: fwd.finger_gap((N, N), v, 0.01),
    ("forward.SceneFrames", "spacing"): lambda v: fwd.SceneFrames(None, HS, True, (N,), v, np.zeros(1), None,
                                                                  np.ones(1), 1e6),
    ("forward.solve_scan", "spacing"): lambda v: fwd.solve_scan(HS, (np.linspace(-1, 1, N) ** 2 * 1e-6)[None], v,
                                                                normal_force=1.0),
    ("forward.SensorReadout", "spacing"): lambda v: fwd.SensorReadout(
        HS, (N,), v, SensorArray(positions_m=[[0.0, 0.0]], depth_m=1e-3, components=("zz",))),
    ("inversion.ContactScan", "spacing"): lambda v: _cell_scan(spacing=v),
    ("inversion.ContactScan", "young_modulus"): lambda v: _cell_scan(young_modulus=v),
    ("inversion.ContactScan", "poisson_ratio"): lambda v: _cell_scan(poisson_ratio=v),
    ("inversion.scene_scan", "spacing"): lambda v: inv.scene_scan(_surface_cell()[0], spacing=v, grid_spacing=2.5e-5),
    ("inversion.invert_surface", "spacing"): lambda v: inv.invert_surface(
        *_surface_cell(), spacing=v, grid_spacing=2.5e-5, prior=inv.StationaryPrior(1e-12, 1e-4),
        rng=np.random.default_rng(0), max_iter=1, n_draws=5),
    ("forward.pressure_from_deflection", "spacing"): lambda v: fwd.pressure_from_deflection(np.zeros(N), v, 1e6, 0.5),
    ("forward.pressure_from_deflection", "young_modulus"): (
        lambda v: fwd.pressure_from_deflection(np.zeros(N), H, v, 0.5)),
    ("forward.pressure_from_deflection", "nu"): lambda v: fwd.pressure_from_deflection(np.zeros(N), H, 1e6, v),
    ("forward.dcfft_stress", "nu"): lambda v: fwd.dcfft_stress(LOAD, [1e-3], nu=v, components=("zz",)),
    ("forward.dcfft_stress", "components"): lambda v: fwd.dcfft_stress(LOAD, [1e-3], components=v),
    ("forward.transfer", "depth"): lambda v: fwd.transfer(np.ones(3), None, v, 0.5, "p", ("zz",)),
    ("forward.transfer", "nu"): lambda v: fwd.transfer(np.ones(3), None, 1e-3, v, "p", ("zz",)),
    ("forward.transfer", "components"): lambda v: fwd.transfer(np.ones(3), None, 1e-3, 0.5, "p", v),
    ("forward.point_green", "nu"): lambda v: fwd.point_green("zz", "z", X, 0.0, 1e-3, nu=v),
    ("forward.point_load_stress", "nu"): lambda v: fwd.point_load_stress(X, 0.0, 1e-3, fz=1.0, nu=v),
    ("forward.line_green", "nu"): lambda v: fwd.line_green("zz", "z", X, 1e-3, nu=v),
    ("forward.line_load_stress", "nu"): lambda v: fwd.line_load_stress(X, 1e-3, fz=1.0, nu=v),
    ("forward.halfspace.compliance_matrix", "young_modulus"): lambda v: fwd.halfspace.compliance_matrix(v, 0.5),
    ("forward.halfspace.compliance_matrix", "nu"): lambda v: fwd.halfspace.compliance_matrix(1e6, v),
    ("forward.halfspace.output_weights", "components"): lambda v: fwd.halfspace.output_weights("strain", v, 1e6, 0.5),
    ("forward.halfspace.output_weights", "young_modulus"): (
        lambda v: fwd.halfspace.output_weights("strain", ("zz",), v, 0.5)),
    ("forward.halfspace.output_weights", "nu"): lambda v: fwd.halfspace.output_weights("strain", ("zz",), 1e6, v),
    ("forward.halfspace.largest_strain", "components"): (
        lambda v: fwd.halfspace.largest_strain(np.zeros((1, 1, 2)), "strain", v, 1e6, 0.5)),
    ("forward.halfspace.largest_strain", "young_modulus"): (
        lambda v: fwd.halfspace.largest_strain(np.zeros((1, 1, 2)), "strain", ("zz",), v, 0.5)),
    ("forward.halfspace.largest_strain", "nu"): (
        lambda v: fwd.halfspace.largest_strain(np.zeros((1, 1, 2)), "strain", ("zz",), 1e6, v)),
    ("forward.halfspace.dcfft_kernel_spectrum", "spacing"): (
        lambda v: _kernel_spectrum(spacing=v)),
    ("forward.halfspace.dcfft_kernel_spectrum", "depth"): (
        lambda v: _kernel_spectrum(depth=v)),
    ("forward.halfspace.dcfft_kernel_spectrum", "nu"): lambda v: _kernel_spectrum(nu=v),
    # the layered skin
    ("forward.Layer", "E"): lambda v: fwd.Layer(1e-3, v),
    ("forward.Layer", "nu"): lambda v: fwd.Layer(1e-3, 1e6, v),
    ("forward.LayeredHalfSpace.stress", "depth"): lambda v: LAYERED.stress(LOAD, v, components=("zz",)),
    ("forward.LayeredHalfSpace.stress", "components"): lambda v: LAYERED.stress(LOAD, 1e-4, components=v),
    ("forward.LayeredHalfSpace.strain", "depth"): lambda v: LAYERED.strain(LOAD, v, components=("zz",)),
    ("forward.LayeredHalfSpace.strain", "components"): lambda v: LAYERED.strain(LOAD, 1e-4, components=v),
    ("forward.LayeredHalfSpace.operator", "spacing"): lambda v: LAYERED.operator((N,), v, depth=1e-4),
    ("forward.LayeredHalfSpace.operator", "depth"): lambda v: LAYERED.operator((N,), H, depth=v),
    ("forward.LayeredHalfSpace.operator", "components"): lambda v: LAYERED.operator((N,), H, depth=1e-4, components=v),
    ("forward.LayeredHalfSpace.material_at", "depth"): lambda v: LAYERED.material_at(v),
    ("forward.LayeredHalfSpace.transfer", "depth"): lambda v: LAYERED.transfer(1e3, 0.0, v),
    # viscoelastic layers
    ("forward.ViscoelasticLayeredHalfSpace.transfer", "depth"): lambda v: VLAYERED.transfer(1e3, 0.0, v, 10.0),
    ("forward.ViscoelasticLayeredHalfSpace.deflection_transfer", "depth"):
        lambda v: VLAYERED.deflection_transfer(1e3, 0.0, v, 10.0),
    ("forward.ViscoelasticLayeredHalfSpace.complex_modulus_at", "depth"): lambda v: VLAYERED.complex_modulus_at(v, 1.0),
    ("forward.ViscoelasticLayeredHalfSpace.nu_at", "depth"): lambda v: VLAYERED.nu_at(v),
    ("forward.ViscoelasticLayeredHalfSpace.sliding_pressure", "spacing"):
        lambda v: VLAYERED.sliding_pressure(np.zeros(N), v, 0.1),
    ("forward.ViscoelasticLayeredHalfSpace.steady_sliding", "spacing"):
        lambda v: VLAYERED.steady_sliding(np.zeros(N), v, 0.1, 1e-3, components=("zz",)),
    ("forward.ViscoelasticLayeredHalfSpace.steady_sliding", "depth"):
        lambda v: VLAYERED.steady_sliding(np.zeros(N), H, 0.1, v, components=("zz",)),
    ("forward.ViscoelasticLayeredHalfSpace.steady_sliding", "components"):
        lambda v: VLAYERED.steady_sliding(np.zeros(N), H, 0.1, 1e-3, components=v),
    ("forward.ViscoelasticLayeredHalfSpace.moving_load", "depth"):
        lambda v: VLAYERED.moving_load(LOAD, 0.1, v, components=("zz",)),
    ("forward.ViscoelasticLayeredHalfSpace.moving_load", "components"):
        lambda v: VLAYERED.moving_load(LOAD, 0.1, 1e-3, components=v),
    ("forward.ViscoelasticLayeredHalfSpace.stress", "depth"): lambda v: VLAYERED.stress(LOAD, v, [0.0], components=("zz",)),
    ("forward.ViscoelasticLayeredHalfSpace.stress", "components"):
        lambda v: VLAYERED.stress(LOAD, 1e-3, [0.0], components=v),
    ("forward.ViscoelasticLayeredHalfSpace.strain", "depth"): lambda v: VLAYERED.strain(LOAD, v, [0.0], components=("zz",)),
    ("forward.ViscoelasticLayeredHalfSpace.strain", "components"):
        lambda v: VLAYERED.strain(LOAD, 1e-3, [0.0], components=v),
    ("forward.ViscoelasticLayeredHalfSpace.operator", "spacing"): lambda v: VLAYERED.operator((N,), v, [0.0]),
    ("forward.ViscoelasticLayeredHalfSpace.operator", "depth"): lambda v: VLAYERED.operator((N,), H, [0.0], depth=v),
    ("forward.ViscoelasticLayeredHalfSpace.operator", "components"):
        lambda v: VLAYERED.operator((N,), H, [0.0], components=v),
    ("forward.skin.receptive_field", "depth"): (
        lambda v: fwd.skin.receptive_field(LAYERED, v, spacing=H, half_extent=4 * H)),
    ("forward.skin.receptive_field", "spacing"): (
        lambda v: fwd.skin.receptive_field(LAYERED, 1e-3, spacing=v, half_extent=4 * (v if v > 0 else H))),
    ("forward.skin.tangential_line_strain", "depth"): (
        lambda v: fwd.skin.tangential_line_strain(LAYERED, X, [0.0], [1.0], v)),
    ("forward.skin.tractor_phi_psi", "depth"): lambda v: fwd.skin.tractor_phi_psi(LAYERED, X, [0.0], [1.0], v),
    # scenes, displays, tractors, receptors
    ("forward.rigid_surface_pressure", "spacing"): lambda v: fwd.rigid_surface_pressure(np.zeros(N), v, 1e6),
    ("forward.rigid_surface_pressure", "young_modulus"): lambda v: fwd.rigid_surface_pressure(np.zeros(N), H, v),
    ("forward.rigid_surface_pressure", "poisson_ratio"): (
        lambda v: fwd.rigid_surface_pressure(np.zeros(N), H, 1e6, poisson_ratio=v)),
    ("forward.sliding_sinusoid_strain", "depth"): lambda v: fwd.sliding_sinusoid_strain(X, v, 1e-5, 2e-3),
    ("forward.sliding_sinusoid_strain", "nu"): lambda v: fwd.sliding_sinusoid_strain(X, 1e-3, 1e-5, 2e-3, nu=v),
    ("forward.tractor_row_strain", "depth"): lambda v: fwd.tractor_row_strain(X, v, [0.0], [1.0], 1e6),
    ("forward.tractor_row_strain", "young_modulus"): lambda v: fwd.tractor_row_strain(X, 1e-3, [0.0], [1.0], v),
    ("forward.tractor_row_strain", "nu"): lambda v: fwd.tractor_row_strain(X, 1e-3, [0.0], [1.0], 1e6, nu=v),
    ("forward.display_row_strain", "depth"): (
        lambda v: fwd.display_row_strain(DISPLAY, X, v, ROW, 1e6)),
    ("forward.display_row_strain", "young_modulus"): (
        lambda v: fwd.display_row_strain(DISPLAY, X, 1e-3, ROW, v)),
    ("forward.display_row_strain", "nu"): (
        lambda v: fwd.display_row_strain(DISPLAY, X, 1e-3, ROW, 1e6, nu=v)),
    ("forward.render_virtual_surface", "depth"): (
        lambda v: fwd.render_virtual_surface(DISPLAY, _height, 0.02, [0.0, 1e-3], X, v, 1.0, 1e6)),
    ("forward.render_virtual_surface", "young_modulus"): (
        lambda v: fwd.render_virtual_surface(DISPLAY, _height, 0.02, [0.0, 1e-3], X, 1e-3, 1.0, v)),
    ("forward.render_virtual_surface", "nu"): (
        lambda v: fwd.render_virtual_surface(DISPLAY, _height, 0.02, [0.0, 1e-3], X, 1e-3, 1.0, 1e6, nu=v)),
    ("forward.display_patch_strain_3d", "young_modulus"): (
        lambda v: fwd.display_patch_strain_3d(DISPLAY, [[0.0, 0.0, 1e-3]], np.zeros(DISPLAY.shape), v)),
    ("forward.display_patch_strain_3d", "nu"): (
        lambda v: fwd.display_patch_strain_3d(DISPLAY, [[0.0, 0.0, 1e-3]], np.zeros(DISPLAY.shape), 1e6, nu=v)),
    ("forward.pair_phi_psi", "depth"): lambda v: fwd.pair_phi_psi(X, 1e-3, v),
    ("forward.array_phi_psi", "depth"): lambda v: fwd.array_phi_psi(X, 1e-3, v),
    ("forward.optimal_half_spacing", "depth"): lambda v: fwd.optimal_half_spacing(v, grid_points=20),
    ("forward.matching_line_load", "depth"): lambda v: fwd.matching_line_load(1e-5, 2e-3, v, 1e6, _design(v)),
    ("forward.matching_line_load", "young_modulus"): lambda v: fwd.matching_line_load(1e-5, 2e-3, 1e-3, v, DESIGNS[1e-3]),
    ("forward.matching_traction_amplitude", "depth"): (
        lambda v: fwd.matching_traction_amplitude(1e-5, 2e-3, v, 1e6, _design(v))),
    ("forward.matching_traction_amplitude", "young_modulus"): (
        lambda v: fwd.matching_traction_amplitude(1e-5, 2e-3, 1e-3, v, DESIGNS[1e-3])),
    ("forward.max_virtual_amplitude", "depth"): lambda v: fwd.max_virtual_amplitude(1e3, 2e-3, v, 1e6, _design(v)),
    ("forward.max_virtual_amplitude", "young_modulus"): lambda v: fwd.max_virtual_amplitude(1e3, 2e-3, 1e-3, v, DESIGNS[1e-3]),
    ("forward.ReceptorHypothesis", "components"): lambda v: fwd.ReceptorHypothesis(components=v, depths=(1e-3,)),
    # the inversion, as it is today
    ("inversion.halfspace_fourier_operator", "spacing"): lambda v: inv.halfspace_fourier_operator((N,), v, 1e-3),
    ("inversion.halfspace_fourier_operator", "depth"): lambda v: inv.halfspace_fourier_operator((N,), H, v),
    ("inversion.halfspace_fourier_operator", "nu"): lambda v: inv.halfspace_fourier_operator((N,), H, 1e-3, nu=v),
    ("inversion.halfspace_strain_operator", "spacing"): lambda v: inv.halfspace_strain_operator((N,), v, 1e-3, 1e6),
    ("inversion.halfspace_strain_operator", "depth"): lambda v: inv.halfspace_strain_operator((N,), H, v, 1e6),
    ("inversion.halfspace_strain_operator", "young_modulus"): (
        lambda v: inv.halfspace_strain_operator((N,), H, 1e-3, v)),
    ("inversion.halfspace_strain_operator", "nu"): lambda v: inv.halfspace_strain_operator((N,), H, 1e-3, 1e6, nu=v),
    ("inversion.rigid_surface_height_operator", "spacing"): lambda v: inv.rigid_surface_height_operator(N, v, 1e-3, 1e6),
    ("inversion.rigid_surface_height_operator", "depth"): lambda v: inv.rigid_surface_height_operator(N, H, v, 1e6),
    ("inversion.rigid_surface_height_operator", "young_modulus"): (
        lambda v: inv.rigid_surface_height_operator(N, H, 1e-3, v)),
    ("inversion.rigid_surface_height_operator", "poisson_ratio"): (
        lambda v: inv.rigid_surface_height_operator(N, H, 1e-3, 1e6, poisson_ratio=v)),
    ("inversion.rigid_surface_height_strain_operator", "spacing"): (
        lambda v: inv.rigid_surface_height_strain_operator(N, v, 1e-3, 1e6)),
    ("inversion.rigid_surface_height_strain_operator", "depth"): (
        lambda v: inv.rigid_surface_height_strain_operator(N, H, v, 1e6)),
    ("inversion.rigid_surface_height_strain_operator", "young_modulus"): (
        lambda v: inv.rigid_surface_height_strain_operator(N, H, 1e-3, v)),
    ("inversion.rigid_surface_height_strain_operator", "poisson_ratio"): (
        lambda v: inv.rigid_surface_height_strain_operator(N, H, 1e-3, 1e6, poisson_ratio=v)),
    ("inversion.FourierDiagonal", "spacing"): lambda v: inv.FourierDiagonal(np.ones(N), spacing=v),
    ("inversion.tikhonov_prior_spectrum", "spacing"): lambda v: inv.tikhonov_prior_spectrum(1.0, "gradient", 1.0, (N,), v),
    ("inversion.StationaryPrior.spectrum", "spacing"): lambda v: inv.StationaryPrior(variance=1.0).spectrum((N,), v),
    ("inversion.gaussian_posterior", "spacing"): (
        lambda v: inv.gaussian_posterior(inv.halfspace_fourier_operator((N,), H, 1e-3), np.zeros(N),
                                         inv.StationaryPrior(variance=1.0), 1e-3, spacing=v)),
    ("inversion.GaussianPosterior.resolvable_band", "depth"): lambda v: _posterior().resolvable_band(depth=v),
    ("inversion.invert_linear", "spacing"): (
        lambda v: inv.invert_linear(inv.halfspace_fourier_operator((N,), H, 1e-3), np.ones(N), lam=1.0, spacing=v)),
    ("inversion.invert_tv", "spacing"): (
        lambda v: inv.invert_tv(inv.halfspace_fourier_operator((N,), H, 1e-3), np.ones(N), lam=1.0, spacing=v,
                                max_iter=5)),
    ("inversion.GridLoadFamily", "spacing"): lambda v: inv.GridLoadFamily((N,), v, young_modulus=1e6),
    ("inversion.GridLoadFamily", "young_modulus"): lambda v: inv.GridLoadFamily((N,), H, young_modulus=v),
    ("inversion.GridLoadFamily", "nu"): lambda v: inv.GridLoadFamily((N,), H, young_modulus=1e6, nu=v),
    ("inversion.IndentationFamily", "spacing"): lambda v: inv.IndentationFamily((N,), v, 1e6),
    ("inversion.IndentationFamily", "young_modulus"): lambda v: inv.IndentationFamily((N,), H, v),
    ("inversion.IndentationFamily", "nu"): lambda v: inv.IndentationFamily((N,), H, 1e6, nu=v),
    ("inversion.SinusoidFamily", "nu"): lambda v: inv.SinusoidFamily(2e-3, nu=v),
    ("inversion.TractorFamily", "young_modulus"): lambda v: inv.TractorFamily(np.linspace(-1e-3, 1e-3, 3), v),
    ("inversion.TractorFamily", "nu"): lambda v: inv.TractorFamily(np.linspace(-1e-3, 1e-3, 3), 1e6, nu=v),
    ("inversion.TractorFamily.from_display", "young_modulus"): lambda v: inv.TractorFamily.from_display(DISPLAY, v),
    ("inversion.DefectScanModel", "components"): lambda v: inv.DefectScanModel([0.0], [[0.0, 0.0]], components=v),
    ("inversion.DefectScanModel", "poisson_ratio"): (
        lambda v: inv.DefectScanModel([0.0], [[0.0, 0.0]], poisson_ratio=v)),
}

#: public callables whose rule parameters are not inputs a user checks: what they hold was checked
EXEMPT = {
    ("inversion.GaussianPosterior", "spacing"): "a result record: gaussian_posterior fills it with a checked spacing",
    ("inversion.metamer_scan", "young_modulus"): "runs a batch; its young_modulus is checked by TractorFamily.from_display",
    ("forward.halfspace.point_unit", "nu"): "the unchecked formula behind point_green, for inner loops whose inputs "
                                            "were checked once (the defect likelihood)",
    ("forward.ContactSolution", "spacing"): "a result record: solve_contact fills it with a checked spacing",
    ("forward.halfspace.pixel_influence", "E"): "the unchecked formula behind HalfSpace.surface_influence",
    ("forward.halfspace.pixel_influence", "nu"): "the unchecked formula behind HalfSpace.surface_influence",
    ("forward.halfspace.pixel_influence", "spacing"): "the unchecked formula behind HalfSpace.surface_influence",
    ("forward.halfspace.label", "components"): "labels a computed field: the solver (half-space or skin model) "
                                               "checked its components",
}


def _cases(kind: str):
    for (name, param), call in ENTRY_POINTS.items():
        quantity = QUANTITY.get(param) or {"core.rules.depth": "depth", "core.rules.depths": "depth",
                                           "core.rules.spacing": "spacing"}.get(name) or name.rsplit(".", 1)[1]
        rule = RULES[quantity]
        for value in getattr(rule, kind):
            yield pytest.param(call, param, value, rule.message, id=f"{name}:{param}={value!r}")


def _names_the_argument(message: str, param: str) -> bool:
    return re.match(rf"\W*{re.escape(param)}\b", message) is not None


@pytest.mark.parametrize(("call", "param", "value", "message"), list(_cases("good")))
def test_every_entry_point_accepts_the_good_values(call, param, value, message):
    try:
        call(value)
    except ValueError as err:  # another argument may object; this one must not
        assert not (_names_the_argument(str(err), param) or re.search(message, str(err))), str(err)


@pytest.mark.parametrize(("call", "param", "value", "message"), list(_cases("bad")))
def test_every_entry_point_refuses_the_bad_values_with_the_rule(call, param, value, message):
    with pytest.raises(ValueError, match=message):
        call(value)


# ----------------------------------------------------------------------------- the walker
FACES = ("core", "data_schemas", "forward", "forward.halfspace", "forward.contact", "forward.skin", "inversion",
         "experiments", "demo")


def _public_callables():
    """(public names, callable) for every function, class and public method on a face."""
    seen: dict[int, tuple[list[str], Callable]] = {}
    for face in FACES:
        module = importlib.import_module(f"tactilab.{face}")
        for name in getattr(module, "__all__", ()):
            if name.startswith("_") or name in ("rules",):
                continue
            obj = getattr(module, name)
            items = []
            if inspect.isclass(obj):
                items.append((f"{face}.{name}", obj))
                for attr, member in vars(obj).items():
                    member = member.__func__ if isinstance(member, (staticmethod, classmethod)) else member
                    abstract = getattr(member, "__isabstractmethod__", False)  # its overrides are listed
                    if not attr.startswith("_") and inspect.isfunction(member) and not abstract:
                        items.append((f"{face}.{name}.{attr}", member))
            elif callable(obj):
                items.append((f"{face}.{name}", obj))
            for public, target in items:
                seen.setdefault(id(target), ([], target))[0].append(public)
    return list(seen.values())


def _rule_parameters(target) -> list[str]:
    try:
        parameters = inspect.signature(target).parameters
    except (TypeError, ValueError):  # a builtin without a signature takes no rule parameter of ours
        return []
    return [p for p in parameters if p in QUANTITY]


def test_every_rule_parameter_of_every_face_is_in_the_table():
    covered = set(ENTRY_POINTS) | set(EXEMPT)
    missing = []
    for names, target in _public_callables():
        for param in _rule_parameters(target):
            if not any((name, param) in covered for name in names):
                missing.append(f"{names[0]}({param}=...)")
    assert not missing, ("add these to ENTRY_POINTS in tests/test_rules.py (and check them with "
                         f"tactilab.core.rules): {sorted(missing)}")


def test_the_walker_sees_methods_and_classes():
    found = {name for names, _ in _public_callables() for name in names}
    assert {"forward.HalfSpace", "forward.HalfSpace.stress", "data_schemas.SkinMaterial",
            "inversion.TractorFamily.from_display"} <= found
    assert _rule_parameters(fwd.HalfSpace.stress) == ["depth", "components"]


def test_every_table_entry_names_a_real_parameter():
    """A renamed parameter must not leave a stale entry that checks nothing."""
    for (name, param) in [*ENTRY_POINTS, *EXEMPT]:
        if name.startswith("core.rules."):
            target = getattr(rules, name.rsplit(".", 1)[1])
        else:
            face, _, rest = name.partition(".")
            if rest.startswith("halfspace."):
                face, rest = "forward.halfspace", rest.removeprefix("halfspace.")
            target = importlib.import_module(f"tactilab.{face}")
            for part in rest.split("."):
                target = getattr(target, part)
        assert param in inspect.signature(target).parameters, f"{name} has no parameter {param!r}"


# ----------------------------------------------------------------------------- the two relaxations
@pytest.mark.parametrize("alias, name", [("xz", "zx"), ("zy", "yz"), ("yx", "xy")])
def test_relaxation_sensor_records_accept_the_component_aliases_like_the_solver(alias, name):
    sensors = SensorArray(positions_m=[[0, 0]], depth_m=1e-3, components=["zz", alias])
    assert sensors.components == ("zz", name) == rules.components(["zz", alias])
    via_solver = HS.stress(LOAD, 1e-3, components=("zz", alias)).data["stress"].sel(component=name)
    direct = HS.stress(LOAD, 1e-3, components=("zz", name)).data["stress"].sel(component=name)
    np.testing.assert_array_equal(via_solver.values, direct.values)


NU_ENTRY_POINTS = [pytest.param(call, id=f"{name}:{param}") for (name, param), call in ENTRY_POINTS.items()
                   if QUANTITY.get(param) == "poisson_ratio" or name == "core.rules.poisson_ratio"]


@pytest.mark.parametrize("nu", [-0.5, 0.0, 0.49, 0.5])
@pytest.mark.parametrize("call", NU_ENTRY_POINTS)
def test_relaxation_poisson_ratio_is_minus_one_to_one_half_at_every_entry_point(call, nu):
    """nu in (-1, 0.5] wherever nu enters (forward/surfaces.py and the inversion's operators used to
    require [0, 0.5])."""
    call(nu)


@pytest.mark.parametrize("nu", [-0.5, 0.0, 0.49, 0.5])
def test_relaxation_an_auxetic_material_gives_the_closed_form_pressure(nu):
    """The plane-strain modulus E / (1 - nu^2) of the material record is the rigid-surface pressure's
    factor (P~ = E* rho H~ / 2), for nu < 0 too."""
    material = SkinMaterial(young_modulus_pa=1e6, poisson_ratio=nu)
    heights = 1e-6 * np.cos(2 * np.pi * np.arange(N) / N)
    k = 2 * np.pi / (N * H)
    np.testing.assert_allclose(fwd.rigid_surface_pressure(heights, H, 1e6, nu).p,
                               material.plane_strain_modulus_pa * k / 2 * heights, atol=1e-9)


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2", None])
def test_workers_is_one_rule(bad):
    from tactilab.core import rules
    assert rules.workers(2) == 2 and rules.workers(np.int64(1)) == 1
    with pytest.raises(ValueError, match=r"workers: threads must be a positive integer, got .*; e.g. 1 or 2"):
        rules.workers(bad)
