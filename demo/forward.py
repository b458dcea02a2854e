"""Demo section for ``tactilab demo``: a sliding fingertip's strain at two receptor depths.

A Hertz fingertip contact (0.8 N, finger radius 10 mm, skin E = 0.5 MPa, nu = 0.5) slides
with friction 0.4: normal pressure plus tangential traction. The half-space facade picks
its method from the scene and the tolerance, reports it and its error estimate, and the
deviatoric strain (the part an incompressible medium can carry as information) is mapped.
"""

from __future__ import annotations

import pathlib
from collections.abc import Iterator

import numpy as np

from tactilab.core import write_netcdf
from tactilab.forward import HalfSpace, HertzContact, SurfaceLoad, interfacial_traction, plot_field

DEPTHS_M = (1.0e-3, 2.0e-3)  # receptor depths (Merkel ~1 mm, Ruffini/Meissner deeper)


def fingertip_load(n: int = 128, spacing: float = 1e-4, force: float = 0.8, friction: float = 0.4,
                   radius: float = 10e-3, young_modulus: float = 0.5e6) -> tuple[SurfaceLoad, HertzContact]:
    """The demo's sliding Hertz contact sampled on an (n, n) grid; SI units."""
    contact = HertzContact(normal_force=force, finger_radius=radius, young_modulus=young_modulus,
                           poisson_ratio=0.5)
    x = (np.arange(n) - n // 2) * spacing
    xx, yy = np.meshgrid(x, x)
    p, qx = interfacial_traction(contact, xx, yy, friction=friction, condition="sliding")
    return SurfaceLoad(p=p, qx=qx, spacing=spacing), contact


def run_demo(report_dir: pathlib.Path, progress: bool = True) -> Iterator[str]:
    """Compute and map the strain under a sliding fingertip; yield report lines."""
    out = pathlib.Path(report_dir) / "forward"
    out.mkdir(parents=True, exist_ok=True)
    load, contact = fingertip_load()
    hs = HalfSpace(E=contact.young_modulus, nu=0.5)
    yield (f"forward: Hertz fingertip 0.8 N, contact radius {contact.contact_radius * 1e3:.2f} mm, "
           f"peak pressure {contact.peak_pressure / 1e3:.1f} kPa, friction 0.4, grid {load.shape} "
           f"at {load.dx * 1e3:.2f} mm")
    result = hs.strain(load, DEPTHS_M, invariants=True)
    ds = result.data
    yield (f"forward: strain at depths {', '.join(f'{z * 1e3:.1f}' for z in DEPTHS_M)} mm by "
           f"'{result.method}' ({result.reason}); estimated relative error {result.error_estimate:.1e}")
    vol = float(np.abs(ds["volumetric"]).max() / np.abs(ds["strain"]).max())
    yield f"forward: incompressible check: max |tr eps| / max |eps| = {vol:.1e} (nu = 0.5)"
    dev = ds["deviatoric"].sel(component=["xx", "zz", "zx"])
    dev.attrs.update(quantity="strain", units="1")
    f1 = plot_field(dev, out / "deviatoric_strain.png",
                    title="deviatoric strain under a sliding fingertip (tensor shear)")
    vm = ds["von_mises"].expand_dims(component=["von Mises"], axis=1)
    vm.attrs.update(quantity="strain", units="1")
    f2 = plot_field(vm, out / "von_mises_strain.png", title="equivalent (von Mises) strain")
    peak = ds["von_mises"].max(dim=("x", "y")).values
    yield ("forward: peak equivalent strain " + ", ".join(
        f"{v:.2e} at {z * 1e3:.1f} mm" for v, z in zip(peak, DEPTHS_M)))
    nc = out / "fingertip_strain.nc"
    write_netcdf(ds, nc)
    yield f"forward: wrote {f1.name}, {f2.name}, {nc.name} in {out}"
