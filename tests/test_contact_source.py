"""``TransductionModel(source="contact")``: a physical grating pressed by a finger, through the solved contact.

Oracles: in full contact (a shallow grating) the solved tractions are the linear superposition
that full contact implies (the finger's Hertz pressure plus the texture's E* |k| H / 2, friction
q = mu p on both), so the strain under them matches the strain of that superposition; where the
grating is deep the skin leaves the troughs (contact fraction < 1, exactly where the superposition
asks for a negative pressure), and the model departs from the superposition and from the surface
formula.
"""

from __future__ import annotations

import numpy as np
import pytest

from tactilab.data_schemas.experiment import Stimulus
from tactilab.experiments.modelling import FingerContact, TransductionModel
from tactilab.forward import SurfaceLoad

DEPTH = 0.25e-3


def _grating(amplitude):
    return Stimulus(amplitude_m=amplitude, pitch_m=1e-3, speed_m_per_s=0.02, duration_s=0.1)


def _linear(fc, s):
    """The superposition full contact implies, per offset: (Hertz pressure, texture pressure) on the grid."""
    x, dx = fc.grid(s)
    xx, yy = np.meshgrid(x, x)
    disc = np.hypot(xx, yy) < fc.hertz.contact_radius
    e_star = fc.young_modulus / (1 - fc.poisson_ratio**2)
    k = 2 * np.pi / s.pitch_m
    hertz = fc.hertz.pressure(xx, yy)
    textures = [e_star * k * fc.heights(s, xx, j * s.pitch_m / fc.n_phases) / 2 * disc for j in range(fc.n_phases)]
    return hertz, textures, dx, disc


def _strain(fc, s, p, dx):
    load = SurfaceLoad(p=p, qx=-fc.friction * p, spacing=dx)  # the grating slides along -x: q on the skin along -x
    field = fc.skin.strain(load, [DEPTH], points=fc.receptors(s), tol=1e-4).data["strain"]
    return field.transpose("depth", "point", "component").values


def _inner(fc, s):
    """Receptors away from the contact's edge (where the edge's shift is outside the superposition)."""
    return np.abs(fc.receptors(s)[:, 0]) < 0.3 * fc.hertz.contact_radius


@pytest.fixture(scope="module")
def finger():
    return FingerContact(20e-3, 1.0, 0.0, n_phases=2)


def test_full_contact_matches_the_linear_superposition(finger):
    s = _grating(0.1e-6)
    # the whole field, friction included (q = mu p on the finger's and the texture's pressure alike)
    rubbing = FingerContact(20e-3, 1.0, 0.5, n_phases=1)
    assert rubbing.contact_fraction(s) == 1.0
    hertz, textures, dx, _ = _linear(rubbing, s)
    total = _strain(rubbing, s, hertz + textures[0], dx)
    assert np.abs(rubbing.total_strain(s, [DEPTH]) - total).max() < 0.01 * np.abs(total).max()
    # the texture's part, at the receptors away from the contact's edge (whose shift the superposition lacks)
    assert finger.contact_fraction(s) == 1.0
    hertz, textures, dx, _ = _linear(finger, s)
    inner = np.tile(_inner(finger, s), finger.n_phases)
    texture = np.concatenate([_strain(finger, s, t, dx) for t in textures], axis=1)[:, inner]
    assert np.abs(finger.strain(s, [DEPTH])[:, inner] - texture).max() < 0.02 * np.abs(texture).max()


def test_partial_contact_departs_from_the_superposition_where_the_skin_leaves_the_troughs(finger):
    s = _grating(40e-6)
    hertz, textures, dx, disc = _linear(finger, s)
    assert finger.contact_fraction(s) < 0.8
    for sol, t in zip(finger.solutions(s), textures):
        asks_tension = disc & (hertz + t < 0)  # the superposition would pull on the skin here
        assert asks_tension.any() and sol.contact[asks_tension].mean() < 0.05  # the solved contact lets go
    inner = np.tile(_inner(finger, s), finger.n_phases)
    texture = np.concatenate([_strain(finger, s, t, dx) for t in textures], axis=1)[:, inner]
    assert np.abs(finger.strain(s, [DEPTH])[:, inner] - texture).max() > 0.2 * np.abs(texture).max()
    model = TransductionModel(f"zx@{DEPTH * 1e3}mm", source="contact", contact=finger)
    surface = TransductionModel(f"zx@{DEPTH * 1e3}mm")
    assert abs(model.statistic_of(s) / surface.statistic_of(s) - 1) > 0.1
    shallow = _grating(0.1e-6)  # in full contact the two sources agree far better
    assert abs(model.statistic_of(shallow) / surface.statistic_of(shallow) - 1) < 0.1


def test_models_share_the_finger_s_solves_and_a_blank_reads_zero(finger):
    s = _grating(2e-6)
    a = TransductionModel("zx@0.5mm", source="contact", contact=finger)
    b = TransductionModel("xx,zx@0.5mm,1mm", source="contact", contact=finger, statistic="rms")
    first = finger.solutions(s)
    assert a.statistic_of(s) > 0 and b.statistic_of(s) > 0 and finger.solutions(s) is first
    assert a.statistic_of(s.model_copy(update={"amplitude_m": 0.0})) == 0.0
    assert a.name == "zx@0.5mm/contact" and b.name.endswith("/rms/contact")


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="contact: source='contact' needs a FingerContact"):
        TransductionModel("zx@1mm", source="contact")
    with pytest.raises(ValueError, match="friction: must be a finite Coulomb coefficient >= 0"):
        FingerContact(friction=-0.1)
    with pytest.raises(ValueError, match="n_phases: must be a whole number >= 1"):
        FingerContact(n_phases=0)
    with pytest.raises(ValueError, match="finger_radius"):
        FingerContact(finger_radius=-1.0)
    with pytest.raises(ValueError, match="nodes per axis .* above max_nodes = 64"):
        FingerContact(max_nodes=64).grid(Stimulus(amplitude_m=1e-6, pitch_m=0.1e-3, speed_m_per_s=0.02,
                                                  duration_s=0.1))
    with pytest.raises(ValueError, match="stimulus: expected a data_schemas Stimulus"):
        FingerContact().solutions("grating")


PROTOCOL = """
name = "physicalgrating"
seed = 4
iti_s = 0
[task]
kind = "2ifc"
[stimulus]
amplitude_m = "2um"
pitch_m = "2mm"
speed_m_per_s = "20mm/s"
duration_s = "50ms"
ramp_s = "5ms"
[procedure]
method = "constant_stimuli"
parameter = "amplitude_m"
levels = ["1um", "4um"]
repeats_per_block = 2
n_blocks = 1
"""
FINGER = """
[finger]
finger_radius_m = "10mm"
normal_force_n = "0.5N"
friction = 0.5
young_modulus_pa = "1MPa"
"""


def test_the_cli_observer_feels_the_protocol_s_finger_and_resume_rebuilds_it(tmp_path, capsys):
    from tactilab.cli.main import main
    from tactilab.data_schemas.experiment import Protocol
    from tactilab.experiments.session import SessionLog

    (tmp_path / "p.toml").write_text(PROTOCOL + FINGER)
    argv = ["experiment", "run", str(tmp_path / "p.toml"), "--subject", "S01", "--responses", "simulated",
            "--no-wait", "--quiet", "--out", str(tmp_path / "out"), "--observer", "zx@1mm",
            "--observer-strain", "contact", "--observer-threshold", "1e-4"]
    assert main(argv) == 0
    (session,) = (tmp_path / "out").glob("*.sqlite")
    log = SessionLog(session)
    meta = log.meta()
    log.close()
    assert meta["responses_config"]["strain"] == "contact"
    finger = Protocol.model_validate(meta["protocol"]).finger
    assert (finger.finger_radius_m, finger.normal_force_n, finger.young_modulus_pa) == (10e-3, 0.5, 1e6)
    # a resume rebuilds the observer from the recorded configuration and the protocol's [finger]
    import argparse

    from tactilab.cli.experiment_observer import observer_responses

    args = argparse.Namespace(observer=None, observer_statistic=None, observer_threshold=None, observer_strain=None)
    rebuilt = observer_responses("simulated", Protocol.model_validate(meta["protocol"]), None, args,
                                 meta["responses_config"])
    assert rebuilt.model.source == "contact" and rebuilt.model.contact.normal_force == 0.5
    assert dict(rebuilt.config) == meta["responses_config"]
    # the default observer reads no hypothesis: 'contact' needs one
    capsys.readouterr()
    assert main([a for a in argv if a not in ("--observer", "zx@1mm")]) != 0
    assert "'contact' is read through a receptor hypothesis" in capsys.readouterr().err
    # without a [finger] the contact has nothing to press the grating: refused, naming the table
    (tmp_path / "bare.toml").write_text(PROTOCOL)
    capsys.readouterr()
    assert main([*argv[:2], str(tmp_path / "bare.toml"), *argv[3:]]) != 0
    assert "--observer-strain: 'contact' needs the finger that presses the gratings: add a [finger] table" in \
        capsys.readouterr().err


def test_a_finger_table_is_validated_with_units():
    from tactilab.data_schemas.experiment import Protocol
    import tomllib

    data = tomllib.loads(PROTOCOL + FINGER)
    assert Protocol.model_validate(data).finger.normal_force_n == 0.5
    for key, value, match in (("friction", -0.5, "friction: must be a Coulomb coefficient >= 0"),
                              ("normal_force_n", "-1N", "normal_force_n"),
                              ("poisson_ratio", 0.7, "poisson_ratio")):
        bad = {**data, "finger": {**data["finger"], key: value}}
        with pytest.raises(ValueError, match=match):
            Protocol.model_validate(bad)
