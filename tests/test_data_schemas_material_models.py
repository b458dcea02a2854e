"""SkinMaterial's viscoelastic and layered models: files with units, JSON round trip, every refusal."""

from __future__ import annotations

import math

import pytest

from tactilab.data_schemas import ElasticBase, PronyTerm, SkinLayer, SkinMaterial, read_material
from tactilab.forward import HalfSpace, Layer, LayeredHalfSpace, ViscoelasticHalfSpace, skin_from_material


def _write(tmp_path, text, name="material.toml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_prony_terms_as_pairs_or_tables_with_units(tmp_path):
    path = _write(tmp_path, '[material]\nmodel = "prony"\nyoung_modulus = "0.2MPa"\n'
                            'terms = [["1MPa", "4ms"], {modulus = "0.5MPa", relaxation_time = "70ms"}]\n')
    m = read_material(path)
    assert m.model == "prony" and m.young_modulus_pa == 2e5
    assert m.prony_terms == ((1e6, 4e-3), (5e5, 0.07))
    assert SkinMaterial.from_json(m.to_json()) == m
    skin = skin_from_material(m)
    assert isinstance(skin, ViscoelasticHalfSpace)
    assert skin.prony.E_0 == pytest.approx(1.7e6) and skin.prony.E_inf == 2e5


def test_sls_and_a_file_that_is_the_material_table(tmp_path):
    path = _write(tmp_path, 'model = "sls"\nyoung_modulus = "100kPa"\ninstantaneous_modulus = "300kPa"\n'
                            'relaxation_time = "50ms"\npoisson_ratio = 0.49\n')
    m = read_material(path)
    assert m.prony_terms == ((2e5, 0.05),) and m.is_viscoelastic and not m.is_layered
    skin = skin_from_material(m)
    assert skin.nu == 0.49 and skin.prony.E_0 == pytest.approx(3e5)


def test_elastic_material_builds_the_half_space(tmp_path):
    m = read_material(_write(tmp_path, '[material]\nyoung_modulus = "1MPa"\npoisson_ratio = 0.45\n'))
    skin = skin_from_material(m)
    assert isinstance(skin, HalfSpace) and (skin.E, skin.nu) == (1e6, 0.45)


def test_layers_on_a_rigid_or_elastic_base(tmp_path):
    m = read_material(_write(tmp_path, '[material]\nlayers = [{thickness = "4mm", young_modulus = "0.1MPa", '
                                       'poisson_ratio = 0.49}, {thickness = "1mm", young_modulus = "1MPa"}]\n'
                                       'base = "rigid"\n'))
    assert m.is_layered and m.young_modulus_pa == 1e5 and m.poisson_ratio == 0.49  # the top layer's
    assert m.layers[1] == SkinLayer(thickness_m=1e-3, young_modulus_pa=1e6)
    on_tissue = read_material(_write(tmp_path, '[material]\nlayers = [{thickness = "4mm", young_modulus = "0.1MPa"}]\n'
                                               'base = {young_modulus = "1MPa", poisson_ratio = 0.45}\n', "b.toml"))
    assert on_tissue.base == ElasticBase(young_modulus_pa=1e6, poisson_ratio=0.45)
    assert SkinMaterial.from_json(on_tissue.to_json()) == on_tissue
    stack = skin_from_material(m)
    assert isinstance(stack, LayeredHalfSpace) and stack.rigid_base and stack.thickness == pytest.approx(5e-3)
    assert stack.layers == (Layer(4e-3, 1e5, 0.49), Layer(1e-3, 1e6, 0.5))
    on = skin_from_material(on_tissue)
    assert not on.rigid_base and (on.base.E, on.base.nu) == (1e6, 0.45)


@pytest.mark.parametrize("fields, match", [
    (dict(model="prony"), r"terms: model 'prony' needs at least one Prony term"),
    (dict(terms=[PronyTerm(modulus_pa=1e6, relaxation_time_s=0.1)]), r"terms: only model 'prony' takes Prony terms"),
    (dict(model="prony", terms=[dict(modulus_pa=1e6, relaxation_time_s=-0.1)]),
     r"relaxation_time_s must be > 0 \(a relaxation time\), got -0.1"),
    (dict(model="prony", terms=[dict(modulus_pa=0.0, relaxation_time_s=0.1)]),
     r"modulus_pa must be > 0 \(each Prony term needs a spring modulus\), got 0.0"),
    (dict(model="prony", terms=[dict(modulus_pa=math.nan, relaxation_time_s=0.1)]), r"modulus_pa must be finite, got nan"),
    (dict(model="sls", instantaneous_modulus_pa=3e6), r"model 'sls' needs both"),
    (dict(model="sls", instantaneous_modulus_pa=5e5, relaxation_time_s=0.1),
     r"instantaneous_modulus_pa: a standard linear solid stiffens on fast loading"),
    (dict(relaxation_time_s=0.1), r"only model 'sls' takes them, got model 'elastic'"),
    (dict(model="maxwell"), r"model"),
    (dict(base="rigid"), r"base: is what the layers lie on, but there are no layers"),
])
def test_material_model_rules(fields, match):
    with pytest.raises(ValueError, match=match):
        SkinMaterial(**{"young_modulus_pa": 1e6, **fields})


@pytest.mark.parametrize("fields, match", [
    (dict(layers=[dict(thickness_m=0.0, young_modulus_pa=1e5)]),
     r"thickness_m must be > 0 \(a layer of zero thickness is no layer\), got 0.0"),
    (dict(layers=[dict(thickness_m=-1e-3, young_modulus_pa=1e5)]), r"thickness_m must be > 0"),
    (dict(layers=[dict(thickness_m=1e-3, young_modulus_pa=1e5, poisson_ratio=0.6)]),
     r"poisson_ratio: Poisson's ratio must lie in \(-1, 0.5\]"),
    (dict(layers=[dict(thickness_m=1e-3, young_modulus_pa=1e5)], young_modulus_pa=2e5),
     r"young_modulus_pa, poisson_ratio: with layers they are the top layer's"),
    (dict(layers=[dict(thickness_m=1e-3, young_modulus_pa=1e5)], model="sls", instantaneous_modulus_pa=3e5,
          relaxation_time_s=0.1, young_modulus_pa=1e5), r"layers: a layered skin takes model .elastic.*own Prony terms"),
    (dict(layers=[dict(thickness_m=1e-3, young_modulus_pa=1e5)], base="bone"), r"base"),
    (dict(layers=[dict(thickness_m=1e-3, young_modulus_pa=1e5)], base=dict(young_modulus_pa=-1.0)),
     r"young_modulus_pa must be > 0"),
])
def test_layer_rules(fields, match):
    with pytest.raises(ValueError, match=match):
        SkinMaterial(**fields)


def test_bad_material_files_are_refused(tmp_path):
    with pytest.raises(ValueError, match=r"a material file must end in .toml or .json, got '.txt'"):
        read_material(_write(tmp_path, "x", "m.txt"))
    with pytest.raises(ValueError, match=r"not valid TOML"):
        read_material(_write(tmp_path, "[material\n"))
    with pytest.raises(ValueError, match=r"relaxation_time.*unit 'mm' measures length, but a time is expected"):
        read_material(_write(tmp_path, '[material]\nmodel = "prony"\nyoung_modulus = "1MPa"\nterms = [["1MPa", "7mm"]]\n'))
    with pytest.raises(ValueError, match=r"material: expected a SkinMaterial record, got dict"):
        skin_from_material({"young_modulus_pa": 1e6})


def test_one_half_space_code_refuses_layers_and_warns_for_relaxation():
    """Scene code that models the skin as one half-space (the finger's scan, the display scene, the defect
    inversion) takes (E, nu) through half_space_constants: layers refused, a viscoelastic skin relaxed."""
    elastic = SkinMaterial(young_modulus_pa=1e6, poisson_ratio=0.45)
    assert elastic.half_space_constants("the scan") == (1e6, 0.45)
    sls = SkinMaterial(young_modulus_pa=1e5, model="sls", instantaneous_modulus_pa=3e5, relaxation_time_s=0.05)
    with pytest.warns(UserWarning, match=r"material: the scan is quasi-static: .* relaxed modulus E_inf = 100000 Pa"):
        assert sls.half_space_constants("the scan") == (1e5, 0.5)
    layered = SkinMaterial(layers=[dict(thickness_m=4e-3, young_modulus_pa=1e5)])
    with pytest.raises(ValueError, match=r"material: the scan models the skin as one elastic half-space, but the "
                                         r"material has 1 layer"):
        layered.half_space_constants("the scan")


def test_half_space_from_material_refuses_layers_and_warns_for_relaxation():
    """HalfSpace.from_material used to return a plain half-space for any material, layers included."""
    assert HalfSpace.from_material(SkinMaterial(young_modulus_pa=1e6, poisson_ratio=0.45)).E == 1e6
    layered = SkinMaterial(layers=[dict(thickness_m=4e-3, young_modulus_pa=1e5)])
    with pytest.raises(ValueError, match=r"material: HalfSpace.from_material .*skin_from_material.* models the skin "
                                         r"as one elastic half-space, but the material has 1 layer"):
        HalfSpace.from_material(layered)
    sls = SkinMaterial(young_modulus_pa=1e5, model="sls", instantaneous_modulus_pa=3e5, relaxation_time_s=0.05)
    with pytest.warns(UserWarning, match=r"quasi-static: .* relaxed modulus E_inf = 100000 Pa"):
        assert HalfSpace.from_material(sls).E == 1e5


def test_a_scene_with_a_layered_material_is_refused_by_the_finger_scan():
    from tactilab.data_schemas import load_example
    from tactilab.forward import BiomimeticFinger

    scene = load_example("fingertip_defect")
    layered = scene.model_copy(update={"material": SkinMaterial(layers=[dict(thickness_m=4e-3, young_modulus_pa=1e5)])})
    with pytest.raises(ValueError, match=r"the biomimetic finger's scan models the skin as one elastic half-space"):
        BiomimeticFinger.from_scene(layered)
