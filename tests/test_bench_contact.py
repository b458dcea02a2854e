"""benchmarks/bench_contact.py runs (tiny grids, no peer) and prints its tables."""

import importlib.util
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _bench():
    spec = importlib.util.spec_from_file_location("bench_contact", ROOT / "benchmarks" / "bench_contact.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.filterwarnings("ignore::UserWarning")  # tiny grids resolve the contacts coarsely (AccuracyWarning)
def test_bench_contact_sections_run(capsys):
    bench = _bench()
    assert bench.main(["--quick", "--sections", "a", "b", "c", "d", "--sizes", "16", "32", "--frames", "2", "--no-peer",
                       "--tol", "1e-6"]) == 0
    out = capsys.readouterr().out
    assert "(a) normal contact" in out and "Tamaas skipped (--no-peer)" in out
    assert "memory at 32^2" in out and "(b) partial slip" in out and "(c) sliding fingertip" in out and "(d) time and iterations" in out
    rows = [line.split() for line in out.splitlines() if line.strip().startswith(("16 ", "32 "))]
    assert all(float(r[5]) > 0 and float(r[6]) > 0 for r in rows[:2])  # (a): iter/floor and loop/floor
    assert len(rows) == 4  # two sizes in (a) and in (d)


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_bench_contact_compares_preconditioners_in_one_run(capsys):
    bench = _bench()
    assert bench.main(["--sections", "a", "--sizes", "32", "--no-peer", "--tol", "1e-6",
                       "--preconditioner", "auto", "fft"]) == 0
    rows = [line.split() for line in capsys.readouterr().out.splitlines() if line.strip().startswith("32 ")]
    assert [r[7] for r in rows] == ["auto", "fft"]


def test_fft_floor_is_positive_and_pads_isolated_grids():
    bench = _bench()
    assert bench.fft_floor((16, 16), True, repeats=1) > 0
    h, pbar = bench.rough_cell(16)
    assert h.shape == (16, 16) and pbar == pytest.approx(0.05 * bench.E_STAR * bench.SLOPE)


@pytest.mark.filterwarnings("ignore::UserWarning")  # tiny grids resolve the contacts coarsely (AccuracyWarning)
@pytest.mark.parametrize("kind", ["auto", "fft"])
def test_bench_contact_phases_splits_the_fine_loop(capsys, monkeypatch, kind):
    spec = importlib.util.spec_from_file_location("bench_contact_phases",
                                                  ROOT / "benchmarks" / "bench_contact_phases.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    from tactilab.forward.contact import ContactCompliance, kernels

    originals = (ContactCompliance.normal, ContactCompliance.preconditioner, kernels.gap)
    assert module.main(["--sizes", "32", "--repeats", "1", "--preconditioner", kind]) == 0
    # the timing wrappers are undone
    assert (ContactCompliance.normal, ContactCompliance.preconditioner, kernels.gap) == originals
    rows = [line.split() for line in capsys.readouterr().out.splitlines() if line.strip().startswith("32 ")]
    assert [r[1] for r in rows] == ["periodic", "isolated"]
    for r in rows:
        loop, parts = float(r[4]), [float(r[i]) for i in (5, 8, 9, 10, 12, 14, 15)]  # A, K, points, f32, f32A, passes, rest
        assert int(r[2]) > 0 and loop > 0 and float(r[5]) > 0 and float(r[8]) > 0
        assert sum(parts) == pytest.approx(loop, abs=0.04)  # printed to 0.01 each
