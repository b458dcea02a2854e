"""Batch options of the CLI (``--batch DIR``, ``--workers N``, ``--scheduler ADDRESS``) and the batch inversion.

:func:`add_worker_options` gives any batch command ``--workers`` and ``--scheduler``
(``tactilab experiment compare | power``, ``tactilab synthesis``, ``tactilab metamer``);
:func:`add_batch_options` adds ``--batch DIR`` for ``tactilab invert``.

``tactilab invert --batch DIR --scene SCENE [--workers N] [--scheduler ADDRESS]`` inverts every
recording file below ``DIR`` with :func:`tactilab.inversion.batch.invert_many`: serial with
``--workers 0``, on a LocalCluster of N one-thread processes without ``--scheduler``, or on the
running Dask scheduler at ADDRESS. A rerun with the same ``--out`` resumes the batch.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def _workers(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0 (0 = serial in-process), got {text!r}") from None
    if n < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0 (0 = serial in-process), got {n}")
    return n


def add_worker_options(parser: argparse.ArgumentParser, *, default_help: str = "serial in-process"):
    """Add ``--workers`` and ``--scheduler`` (an argument group of their own, returned) to a command's parser.

    ``default_help`` says what happens without ``--workers`` (``args.workers`` is then None).
    """
    group = parser.add_argument_group("batch (Dask; needs pip install 'tactilab[dask]' unless --workers 0)")
    group.add_argument("--workers", type=_workers, default=None, metavar="N",
                       help=f"worker processes of a LocalCluster on this machine (count; default: {default_help}); "
                            "0 runs serially in-process")
    group.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="address of a running Dask scheduler (e.g. tcp://host:8786); default: start a "
                            "LocalCluster here (its dashboard address is printed)")
    return group


def add_batch_options(parser: argparse.ArgumentParser) -> None:
    """Add ``--batch``, ``--workers`` and ``--scheduler`` to ``tactilab invert``'s parser."""
    group = add_worker_options(parser, default_help="one per core")
    group.add_argument("--batch", type=Path, default=None, metavar="DIR",
                       help="invert every recording file (.nc, .json, .parquet) below DIR, one task each; results "
                            "in --out (default ./<DIR name>-batch); a rerun with the same --out resumes")


def wants_batch(args: argparse.Namespace) -> bool:
    """True when ``--workers`` or ``--scheduler`` was given (the command then runs as a batch)."""
    return args.workers is not None or args.scheduler is not None


def batch_where(args: argparse.Namespace) -> dict:
    """``workers`` and ``scheduler`` keywords of a batch call: no ``--workers`` means serial (0)."""
    return dict(workers=0 if args.workers is None and args.scheduler is None else args.workers,
                scheduler=args.scheduler)


def _warn_models(folder: Path) -> None:
    """One warning line when recordings of the batch were made with another interface model than the
    modulation the defect inversion assumes (the largest modulation error they state)."""
    from tactilab.data_schemas import read_recording
    from tactilab.data_schemas.interface_model import recording_model

    from .common import print_warning
    from tactilab.inversion.batch import RECORDING_SUFFIXES

    other, errors = {}, []
    for path in sorted(p for p in folder.rglob("*") if p.is_file() and p.suffix in RECORDING_SUFFIXES):
        try:
            stated = recording_model(read_recording(path), path)
        except (OSError, ValueError):  # invert_many reports unreadable files itself
            continue
        if stated is not None and stated["model"] != "modulation":
            other[stated["model"]] = other.get(stated["model"], 0) + 1
            errors.append(stated["errors"].get("modulation"))
    if other:
        known = [e for e in errors if e is not None]
        size = (f"the largest modulation error they state is {max(known):.2g} of the signal" if known
                else "they state no modulation error")
        made = ", ".join(f"{n} with {model!r}" for model, n in sorted(other.items()))
        print_warning("invert", f"{sum(other.values())} recording(s) were made with another interface model ({made}) "
                                f"but the defect inversion assumes the 'modulation' model; {size}")


def run_invert_batch(args: argparse.Namespace) -> int:
    """Run the batch inversion for parsed ``tactilab invert --batch`` arguments; print a closing summary.

    Uses ``args.batch``, ``args.scene``, ``args.out``, ``args.seed``, ``args.workers``,
    ``args.scheduler`` and, when present, ``args.max_steps``, ``args.max_data``,
    ``args.criterion``, ``args.sample``, ``args.quiet``. Returns 0 when every recording was
    inverted, 1 when some failed (listed in ``errors.tsv``).
    """
    from tactilab.inversion.batch import invert_many

    if args.batch is None or not Path(args.batch).is_dir():
        raise ValueError(f"--batch: must be a folder of recording files, got {str(args.batch)!r}; e.g. --batch scans/")
    max_steps = getattr(args, "max_steps", 20000)
    if max_steps < 1:
        raise ValueError(f"--max-steps: must be >= 1 step, got {max_steps}; e.g. 20000")
    from tactilab.inversion import check_max_steps

    sample = tuple(q.strip() for q in getattr(args, "sample", "").split(",") if q.strip())
    check_max_steps(max_steps, 2 + len(sample), name="--max-steps")  # the memory rule, before any task runs
    out = args.out if getattr(args, "out", None) is not None else Path(f"{Path(args.batch).resolve().name}-batch")
    _warn_models(Path(args.batch))
    tree = invert_many(args.batch, args.scene, seed=getattr(args, "seed", 0), out_dir=out, workers=args.workers,
                       scheduler=args.scheduler, sample=sample, max_data=getattr(args, "max_data", 1500),
                       criterion=getattr(args, "criterion", "evidence"), sampler_options={"max_steps": max_steps},
                       progress=not getattr(args, "quiet", False),
                       allow_scene_mismatch=getattr(args, "allow_scene_mismatch", False))
    a = tree.attrs
    print(f"batch: {a['n_run']} recording(s) inverted, {a['n_skipped']} skipped (done before), "
          f"{a['n_failed']} failed, {a['wall_s']:.1f} s (+ {a['gather_s']:.1f} s reading the results back)")
    print(f"files: {Path(out) / 'results'} (one DataTree per recording), {Path(out) / 'invert_many.nc'} (gathered)"
          + (f", {Path(out) / 'errors.tsv'} (failed: {a['failed'].replace(';', ', ')})" if a["n_failed"] else ""))
    return 1 if a["n_failed"] else 0
