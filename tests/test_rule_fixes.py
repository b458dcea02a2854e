"""Every rule's fix names the unit the caller types: SI with an example at a Python entry point,
a unit suffix at a command-line option (a name starting with ``--``)."""

import pytest

from tactilab.core import rules


@pytest.mark.parametrize("call, message", [
    (lambda: rules.young_modulus(0.0), r"young_modulus: .* got 0.0; give E in Pa, e\.g\. 1\.5e6"),
    (lambda: rules.young_modulus(-1.0, "E"), r"E: .* got -1.0; give E in Pa, e\.g\. 1\.5e6"),
    (lambda: rules.young_modulus(0.0, "--young-modulus"), r"--young-modulus: .*; give E with a unit, e\.g\. 1\.5MPa"),
    (lambda: rules.positive(0.0, "width", "m"), r"width: .*; give a finite value > 0 in m, e\.g\. 1\.25e-3"),
    (lambda: rules.positive(0.0, "--width", "m"), r"--width: .*; give a finite value > 0 with a unit, e\.g\. 1\.25mm"),
    (lambda: rules.positive(-2.0, "--limit", "Pa"), r"--limit: .*; give a finite value > 0 with a unit, e\.g\. 1\.5MPa"),
    (lambda: rules.finite(float("nan"), "x0", "m"), r"x0: must be finite, got nan; give a finite number in m, e\.g\."),
    (lambda: rules.depths([-1e-3]), r"depth: .*; give depths below the surface as positive values in m, e\.g\. 1\.25e-3"),
    (lambda: rules.depths([-1e-3], "--depth"), r"--depth: .*; give depths below the surface as positive values with a unit, e\.g\. 1\.25mm"),
    (lambda: rules.spacing(-1.0, 2, "--grid-spacing"), r"--grid-spacing: .*; give it with a unit, e\.g\. 1\.25mm"),
])
def test_every_fix_names_the_unit_the_caller_types(call, message):
    with pytest.raises(ValueError, match=message):
        call()
