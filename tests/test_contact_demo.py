"""The demo's contact section: a fingertip on a rough plate, solved; its lines and files."""

import numpy as np
import xarray as xr

from tactilab.demo import SECTIONS, contact, forward
from tactilab.demo.contact import fingertip_on_rough_plate, run_demo


def test_contact_section_reports_and_writes(tmp_path):
    lines = list(run_demo(tmp_path, progress=False))
    text = "\n".join(lines)
    for phrase in ("real contact area", "of the Hertz disc touches", "peak pressure", "error estimate",
                   "converged", "rough_contact_pressure.png"):
        assert phrase in text, phrase
    with xr.open_dataset(tmp_path / "contact" / "rough_contact.nc", engine="h5netcdf") as ds:
        p = ds["pressure"].values
        cell = float(ds["x"].values[1] - ds["x"].values[0]) ** 2
    assert abs(p.sum() * cell - 0.5) < 1e-9  # the total force is exact
    assert (tmp_path / "contact" / "rough_contact_pressure.png").stat().st_size > 10_000


def test_contact_section_follows_forward_and_its_plate_is_seeded():
    assert SECTIONS.index(contact) == SECTIONS.index(forward) + 1
    a, _ = fingertip_on_rough_plate(n=32)
    b, _ = fingertip_on_rough_plate(n=32)
    np.testing.assert_array_equal(a, b)
