"""Unit conversion at the edges (data_schemas.units)."""

import math

import pytest

from tactilab.data_schemas.units import factor, to_si


@pytest.mark.parametrize("text,dimension,expected", [
    ("1.25mm", "length", 1.25e-3), ("0.1 mm", "length", 1e-4), ("50um", "length", 50e-6),
    ("20kPa", "pressure", 2e4), ("1.5MPa", "pressure", 1.5e6), ("5ms", "time", 5e-3),
    ("0.8N", "force", 0.8), ("5cm/s", "speed", 0.05), ("1kHz", "frequency", 1e3), ("2m", "length", 2.0), (2, "length", 2.0),
])
def test_to_si_is_exact(text, dimension, expected):
    assert to_si(text, dimension) == expected


def test_bare_numbers_take_the_default_unit():
    assert to_si(3, "length", default_unit="mm") == 3e-3
    assert to_si(2.5, "pressure") == 2.5


@pytest.mark.parametrize("value,dimension,message", [
    ("1furlong", "length", "unknown unit 'furlong'"),
    ("1kPa", "length", "measures pressure, but a length is expected"),
    ("abc", "length", "cannot read 'abc' as a quantity"),
    ("nan mm", "length", "must be finite"),
    (True, "length", "got the boolean"),
    ([1], "length", "expected a number or a string"),
    ("1mm", "colour", "dimension: unknown dimension"),
    ("2furlong", "dimensionless", r"unknown unit 'furlong'; use one of 1 or no unit \(SI: 1\)$"),
    ("2mm", "dimensionless", r"measures length, but a dimensionless number is expected; use one of 1 or no unit$"),
])
def test_bad_quantities_are_named(value, dimension, message):
    with pytest.raises(ValueError, match=message):
        to_si(value, dimension, name="--depth")


def test_factor_names_the_argument():
    with pytest.raises(ValueError, match="^--speed: unknown unit"):
        factor("mph", "speed", name="--speed")
    assert math.isclose(factor("mm/s", "speed"), 1e-3)


@pytest.mark.parametrize("text,dimension,fix", [
    ("1.25", "length", "'1.25mm'"), ("50", "pressure", "'50kPa'"), ("5", "time", "'5ms'"),
])
def test_a_bare_number_string_needs_a_unit(text, dimension, fix):
    with pytest.raises(ValueError, match=rf"--opt: '{text}' has no unit, and a {dimension} needs one; "
                                         rf"write it with a unit, e\.g\. {fix}"):
        to_si(text, dimension, name="--opt")
    assert to_si(text, "dimensionless") == float(text)  # dimensionless values stay bare
    assert to_si(text, dimension, default_unit="m" if dimension == "length" else "Pa" if dimension == "pressure"
                 else "s") == float(text)  # a file key that names its unit (depth_m) takes a bare number


@pytest.mark.parametrize("name,dimension,fix", [
    ("--young-modulus", "pressure", "'1.54MPa'"), ("material.young_modulus", "pressure", "'1.54MPa'"),
    ("--traction-limit", "pressure", "'1.54kPa'"), ("--depth", "length", "'1.54mm'"),
    ("--amplitude", "length", "'1.54um'"), ("sinusoid A", "length", "'1.54um'"), ("rough rms", "length", "'1.54um'"),
    ("--watchdog", "time", "'1.54ms'"), ("--max-seconds", "time", "'1.54ms'"), ("force", "force", "'1.54N'"),
])
def test_the_hint_for_a_bare_number_uses_the_options_natural_unit(name, dimension, fix):
    """One rule: a modulus in MPa (not 1000x softer kPa), amplitudes in um, times never bare."""
    with pytest.raises(ValueError, match=rf"'1\.54' has no unit, and a {dimension} needs one; write it with a unit, "
                                         rf"e\.g\. {fix}"):
        to_si("1.54", dimension, name=name)


@pytest.mark.parametrize("text", ["20μm", "20µm", "20 μm", "20um"])
def test_greek_mu_and_the_micro_sign_both_read_as_micro(text):
    assert to_si(text, "length") == 2e-5


def test_greek_mu_in_a_file_key_suffix_and_a_height_unit():
    from tactilab.data_schemas.height_map import _length_factor
    from tactilab.data_schemas.sensors import SensorArray
    from tactilab.data_schemas.unit_keys import convert_units

    assert convert_units(SensorArray, {"depth_μm": 1250})["depth_m"] == pytest.approx(1.25e-3)
    assert _length_factor("μm", "heights") == 1e-6
