"""A finger scene on a layered skin (forward/scene_layered.py, SceneFrames, SensorReadout on a layered skin).

Oracles: the layered skin's own field route (``LayeredHalfSpace.strain`` of the solved tractions,
a padded-grid solve independent of the readout's adjoint weight matrix); the half-space scene,
reproduced by a layer on a half-space of the same material and approached like (a / t)^2 by a
layer of thickness t on a rigid base; the half-space's full-contact pressure E* |k| H~ / 2 under a
deep layer.
"""

import json
import math

import numpy as np
import pytest

from tactilab.cli.main import main
from tactilab.data_schemas import SensorArray, SkinMaterial
from tactilab.data_schemas.recording_io import read_recording_metadata
from tactilab.data_schemas.scene import Contact, Scan, Scene
from tactilab.data_schemas.surface import SinusoidalGrating
from tactilab.forward import HalfSpace, SurfaceLoad, skin_from_material
from tactilab.forward.halfspace import AccuracyWarning
from tactilab.forward.scene_contact import solve_scan
from tactilab.forward.scene_frames import SceneFrames
from tactilab.forward.scene_models import run_model, scene_signals, signal_error
from tactilab.forward.scene_readout import SensorReadout
from tactilab.forward.scene_simulation import simulate_scene

E, NU = 1e6, 0.5
SPACING = 50e-6  # m: a 64 x 64 contact grid for the 1.04 mm Hertz radius below
HALF = SkinMaterial(young_modulus_pa=E, poisson_ratio=NU)


def _layers(thickness, base=None, E_top=E):
    return SkinMaterial(layers=[dict(thickness_m=thickness, young_modulus_pa=E_top, poisson_ratio=NU)], base=base)


def _scene(material, model="exact", amplitude=2e-6, frames=2, tol=0.05):
    """A fingertip (0.2 N, R = 10 mm: a = 1.04 mm) sliding over a 0.5 mm grating; strain sensors 0.5 mm deep."""
    return Scene(material=material, surface=SinusoidalGrating(period_m=0.5e-3, amplitude_m=amplitude),
                 contact=Contact(normal_force_n=0.2, finger_radius_m=0.01, friction_coefficient=0.5, model=model,
                                 tol=tol),
                 sensors=SensorArray.grid(3, 1, 0.4e-3, 0.5e-3, quantity="strain", components=("zz", "zx")),
                 scan=Scan(speed_m_per_s=0.01, duration_s=frames / 2000, sampling_rate_hz=2000))


def _difference(a, b) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


def test_sensors_read_the_layered_strain_of_the_solved_tractions():
    """Each frame's readings are LayeredHalfSpace.strain of that frame's solved tractions at the sensors."""
    scene = _scene(_layers(1e-3))  # a 1 mm pulp on bone: the contact and the strain feel the base
    values, info = scene_signals(scene, grid_spacing=SPACING)
    frames = info["frames"]
    assert info["model"] == "exact" and type(frames.skin).__name__ == "LayeredHalfSpace"
    sol = solve_scan(frames.skin, lambda i: frames.gap(i), frames.spacing, n_frames=frames.n_frames,
                     friction=frames.friction, slide_direction=(frames.direction, 0.0), warm_start=False,
                     tol=1e-10, sensors=frames.readout(), **frames.load)
    assert _difference(values, sol.outputs[0]) <= 1e-4  # the scene's contact tolerance 5e-6; measured 2.5e-5
    arr, readout = scene.sensors, frames.readout()
    assert readout.error_estimate <= readout.tol
    finer = SensorReadout(frames.skin, frames.shape, frames.spacing, arr, window=readout.window,
                          loads=("p", "qx", "qy"), tol=1e-5)  # padded further
    for i in range(frames.n_frames):
        assert sol.normal_force[i] == pytest.approx(0.2, rel=1e-9)
        load = SurfaceLoad(p=sol.pressure[i], qx=sol.qx[i], qy=sol.qy[i], spacing=frames.spacing)
        field = frames.skin.strain(load, arr.depth_m, points=arr.positions_m[:, :2], components=arr.components,
                                   tol=1e-6)
        want = field.data["strain"].values.reshape(len(arr.components), -1).T
        assert _difference(sol.outputs[0][i], want) <= readout.error_estimate  # 2.6e-5 within its bound 6.2e-4
        got = finer.read(sol.pressure[i][None], sol.qx[i][None], sol.qy[i][None])[0][0]
        assert _difference(got, want) <= 1e-6


def test_a_layer_on_the_same_half_space_is_the_half_space_scene():
    half, _ = scene_signals(_scene(HALF), grid_spacing=SPACING)
    same, info = scene_signals(_scene(_layers(0.3e-3, base=dict(young_modulus_pa=E, poisson_ratio=NU))),
                               grid_spacing=SPACING)
    assert _difference(same, half) <= 1e-3  # measured 2.2e-4: the padded grids' truncation


def test_a_deep_layer_on_bone_tends_to_the_half_space_scene_like_its_thickness_squared():
    """At 5 and 15 Hertz radii (a = 1.04 mm) the rigid base moves the signal by 3.7 % and 0.37 %."""
    half, _ = scene_signals(_scene(HALF), grid_spacing=SPACING)
    a = 1.04e-3
    moved = {t: _difference(scene_signals(_scene(_layers(t * a)), grid_spacing=SPACING)[0], half) for t in (5, 15)}
    assert moved[5] <= 0.05 and moved[15] <= 0.005
    assert moved[5] * 5**2 == pytest.approx(moved[15] * 15**2, rel=0.2)  # measured ratio 9.8 against 9


def test_the_linear_model_on_a_layered_skin():
    """Under a deep layer the texture's full-contact pressure is the half-space's E* |k| H~ / 2; in full
    contact (a shallow grating) auto picks the linear model, whose error it states and meets."""
    deep = SceneFrames.from_scene(_scene(_layers(40e-3)), SPACING)
    flat = SceneFrames.from_scene(_scene(HALF), SPACING)
    want = flat.texture_pressure(1)
    assert _difference(deep.texture_pressure(1), want) <= 1e-9
    scene = _scene(_layers(1e-3), model="auto", amplitude=0.05e-6, frames=3)
    values, info = scene_signals(scene, grid_spacing=SPACING)
    assert info["model"] == "linear" and set(info["errors"]) == {"linear"}, info["reason"]
    assert "layered skin" in info["reason"]
    exact = run_model(info["frames"], "exact")
    assert signal_error(values, exact.values) <= info["errors"]["linear"] <= scene.contact.tol


def test_simulate_cli_takes_elastic_layers(tmp_path, capsys):
    text = ('name = "pulp"\n[material]\nlayers = [{thickness = "1mm", young_modulus = "1MPa"}]\n'
            '[surface]\nkind = "sinusoidal_grating"\nperiod = "0.5mm"\namplitude = "2um"\n'
            '[contact]\nnormal_force = "0.2N"\nfinger_radius = "10mm"\nfriction_coefficient = 0.5\nmodel = "exact"\n'
            '[sensors]\nquantity = "strain"\ncomponents = ["zz"]\ndepth = "0.5mm"\n[sensors.grid]\nnx = 3\nny = 1\n'
            'spacing_x = "0.4mm"\n[scan]\nspeed = "10mm/s"\nduration = "1ms"\nsampling_rate = "2kHz"\n')
    path = tmp_path / "pulp.toml"
    path.write_text(text, encoding="utf-8")
    assert main(["simulate", str(path), "--out", str(tmp_path / "out"), "--grid-spacing", "50um", "--quiet",
                 "--json", "--no-plots"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["interface_model"] == "exact"
    assert any("layered skin (1 mm of E = 1000 kPa, nu = 0.5 on a rigid base)" in line for line in summary["computed"])
    attrs = read_recording_metadata(tmp_path / "out" / "recording.nc")["attrs"]
    assert attrs["skin_layers"] == "1 mm of E = 1000 kPa, nu = 0.5 on a rigid base" and attrs["young_modulus_pa"] == E


@pytest.mark.parametrize("material, fields, match", [
    (_layers(1e-3), dict(model="modulation"), r"contact.model: 'modulation' scales the Hertz traction of a "
                                              r"homogeneous half-space .* use model = 'exact', 'linear' or 'auto'"),
    (SkinMaterial(layers=[dict(thickness_m=1e-3, young_modulus_pa=E,
                               terms=[dict(modulus_pa=1e6, relaxation_time_s=0.07)])]), {},
     r"material.layers: a scene simulation takes elastic layers .* a layer has Prony terms"),
])
def test_refusals_on_a_layered_skin(material, fields, match):
    scene = _scene(material, **fields)
    with pytest.raises(ValueError, match=match):
        scene_signals(scene, grid_spacing=SPACING)
    with pytest.raises(ValueError, match=match):
        simulate_scene(scene, "unused", grid_spacing=SPACING, plots=False)


def test_a_periodic_cell_on_layers_is_refused():
    scene = Scene(material=_layers(1e-3), surface=SinusoidalGrating(period_m=1e-3, amplitude_m=1e-6),
                  contact=Contact(mean_pressure_pa=1e3, model="exact"),
                  sensors=SensorArray.grid(1, 1, 1e-4, 0.3e-3, components=("zz",)),
                  scan=Scan(speed_m_per_s=0.01, duration_s=0.002, sampling_rate_hz=1000))
    with pytest.raises(ValueError, match=r"contact.mean_pressure: a periodic cell takes a homogeneous half-space"):
        SceneFrames.from_scene(scene)


def test_readout_tol_is_checked():
    arr = SensorArray.grid(1, 1, 1e-4, 0.3e-3, components=("zz",))
    with pytest.raises(ValueError, match="tol"):
        SensorReadout(HalfSpace(E, NU), (8, 8), 1e-4, arr, tol=-1.0)


@pytest.mark.parametrize("shape, periodic", [((16, 16), True), ((24,), False), ((12, 16), False)])
def test_readout_on_a_layered_grid_equals_its_strain(shape, periodic):
    """Any grid: a periodic one (layers on a half-space, exact), a plane-strain line and an isolated window
    narrower than the sensors' reach (on bone, where the padded grids' truncation is exponentially small)."""
    rng = np.random.default_rng(3)
    base = dict(young_modulus_pa=E / 2, poisson_ratio=0.45) if periodic else None
    skin = skin_from_material(_layers(0.6e-3, base=base))
    h = 1e-4
    positions = [[-0.55e-3, 0.07e-3], [0.13e-3, -0.2e-3], [0.9e-3, 0.0]] if len(shape) == 2 else \
        [[-0.55e-3, 0.0], [0.13e-3, 0.0], [0.9e-3, 0.0]]
    arr = SensorArray(positions_m=positions, depth_m=0.3e-3, quantity="strain", components=("zz", "zx", "xy"))
    # smooth tractions (Gaussians of random centres and amplitudes, 2.5 nodes wide): on a grid, the field between
    # the nodes depends on the padded period through the loads' interpolant, which for rough loads differs at 1e-5
    axes = np.meshgrid(*[(np.arange(n) - n // 2) * h for n in shape], indexing="ij")
    loads = np.array([rng.uniform(0.5e3, 2e3) * np.exp(-sum((x - c) ** 2 for x, c in zip(axes, rng.uniform(
        -2.5 * h, 2.5 * h, len(shape)))) / (2.5 * h) ** 2) for _ in range(3)])
    readout = SensorReadout(skin, shape, h, arr, periodic=periodic, loads=("p", "qx", "qy")[:len(shape) + 1],
                            tol=1e-4)
    got = readout.read(*[v[None] for v in loads[:len(shape) + 1]])[0][0]
    load = SurfaceLoad(**dict(zip(("p", "qx", "qy"), loads[:len(shape) + 1])), spacing=h, periodic=periodic)
    points = np.asarray(positions)[:, :len(shape)]
    if not periodic:  # LayeredHalfSpace.strain reads an isolated load's field within its grid: widen it with zeros
        pad = [(8, 8)] * len(shape)
        load = SurfaceLoad(**{k: np.pad(v, pad) for k, v in load.components.items()}, spacing=h)
    want = skin.strain(load, arr.depth_m, points=points, components=arr.components, tol=1e-4)
    want = want.data["strain"]
    want = want.values.reshape(len(arr.components), -1).T
    assert _difference(got, want) <= 1e-6


def test_readout_warns_when_its_padding_cannot_meet_tol():
    skin = _layers(40e-3)
    arr = SensorArray.grid(1, 1, 1e-4, 0.3e-3, components=("zz",))
    with pytest.warns(AccuracyWarning, match=r"tol: the layered skin's readout on a grid padded 16x per axis keeps"):
        SensorReadout(skin_from_material(skin), (8, 8), 1e-4, arr, loads=("p",), tol=1e-12)


def test_the_smooth_finger_in_partial_slip_on_layers_carries_its_share_of_friction():
    frames = SceneFrames.from_scene(_scene(_layers(1e-3), model="linear"), SPACING)
    p, q = frames._finger_tractions(0.5, fingerprint=False)
    cell = math.prod(frames.spacing)
    assert p.sum() * cell == pytest.approx(0.2, rel=1e-8)
    assert q.sum() * cell == pytest.approx(frames.direction * 0.5 * 0.5 * 0.2, rel=1e-6)
    assert np.all(np.abs(q) <= 0.5 * p + 1e-9 * p.max())  # Coulomb
