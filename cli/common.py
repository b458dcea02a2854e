"""Helpers shared by the command modules (edge handling only, no science)."""

from __future__ import annotations

import contextlib
import json
import os
import sys
import warnings
from dataclasses import dataclass, field
from pathlib import Path


#: every warning printed during the current command, one line each: ``main()`` empties it when a command starts
#: and routes every warning through :func:`print_warning`, so a run summary counts all it printed
PRINTED_WARNINGS: list[str] = []


def print_warning(command: str, message) -> str:
    """Print ``message`` as one ``tactilab COMMAND: warning: ...`` line on stderr and count it.

    The one path for warnings: ``main()``'s ``warnings.showwarning``, :meth:`RunReport.collecting_warnings`
    and a command's own notices all come here, so every warning printed is in the summary's count.
    """
    from tactilab.core.outputs import printable

    text = printable(" ".join(str(message).split()))
    print(f"tactilab {command}: warning: {text}", file=sys.stderr)
    PRINTED_WARNINGS.append(text)
    return text


def make_out(folder: Path, option: str = "--out") -> Path:
    """Create the output folder first, so a bad path fails before the computation, in one line."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OSError(f"{option}: cannot create the output folder {str(folder)!r} ({exc.strerror or exc}); "
                      "choose a writable folder") from None
    return folder


def add_report_options(parser, out: bool = True) -> None:
    """Add ``--json`` (and, for commands that write a folder, ``--force``) to a command's parser."""
    parser.add_argument("--json", action="store_true",
                        help="print only the run summary, as one JSON object on stdout (units in the key names)")
    if out:
        parser.add_argument("--force", action="store_true",
                            help="write into an existing, non-empty --out folder (files of the same name are replaced)")


def choose_out(out: Path | None, default: Path, force: bool = False, option: str = "--out") -> Path:
    """Return the output folder, created; never write into a non-empty folder by accident.

    ``out`` given: used as is, but an existing non-empty folder is refused unless ``force``.
    ``out`` omitted: ``default`` when it is new or empty, else the first free ``default-2``,
    ``default-3``, ... (an earlier run's files are never overwritten).
    """
    if out is not None:
        out = Path(out)
        if out.is_dir() and any(out.iterdir()) and not force:
            raise ValueError(f"{option}: the folder {str(out)!r} exists and is not empty; choose a new folder, "
                             "or add --force to overwrite its files")
        return make_out(out, option)
    default = Path(default)
    candidate, k = default, 1
    while candidate.exists() and (not candidate.is_dir() or any(candidate.iterdir())):
        k += 1
        candidate = default.with_name(f"{default.name}-{k}")
    return make_out(candidate, option)


@contextlib.contextmanager
def staged_outputs(out: Path, created: bool = False):
    """Yield a hidden staging folder inside ``out``; move what was written there into ``out`` only when the
    block succeeds.

    A run that fails part-way (an error, or a warning that ``--strict`` turns into one) leaves no partial
    output behind: the staging folder is removed, and ``out`` itself too when the run created it and it
    is still empty. On success each file replaces its namesake in ``out`` (``--force`` was checked by
    :func:`choose_out`).
    """
    import shutil
    import tempfile

    out = Path(out)
    stage = Path(tempfile.mkdtemp(prefix=".tactilab-partial-", dir=out))
    try:
        yield stage
        for path in sorted(stage.rglob("*")):
            target = out / path.relative_to(stage)
            if path.is_dir():
                target.mkdir(exist_ok=True)
            else:
                os.replace(path, target)
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        if created and not any(out.iterdir()):
            out.rmdir()  # refused: leave no empty folder behind
        raise
    shutil.rmtree(stage, ignore_errors=True)


def _files_below(folder: Path) -> dict[str, float]:
    return {str(p): p.stat().st_mtime_ns for p in sorted(Path(folder).rglob("*")) if p.is_file()}


@dataclass
class RunReport:
    """The summary block that ends a command's run, printed for people or as one JSON object.

    Attributes
    ----------
    command : str
        The subcommand word.
    computed : list of str
        What was computed (one line each; units in the text).
    method : str
        Method used and why.
    error_estimate : str
        Its error estimate, in words with units ("not estimated" when there is none).
    dropped : list of str
        What was left out and why (sensors, samples, components, ...); empty when nothing was.
    warnings : list of str
        Every warning printed during the command, one line each (read-only: :data:`PRINTED_WARNINGS`,
        which also holds those printed before the report existed, e.g. while reading options).
    out : Path or None
        Output folder; ``files`` lists the files written there.
    data : dict
        Machine-readable values for ``--json`` (keys carry their unit, e.g. ``x0_mm``).
    """

    command: str
    computed: list[str] = field(default_factory=list)
    method: str = ""
    error_estimate: str = "not estimated"
    dropped: list[str] = field(default_factory=list)
    out: Path | None = None
    files: list[str] = field(default_factory=list)
    data: dict = field(default_factory=dict)
    _before: dict = field(default_factory=dict, repr=False)

    def watch(self, out: Path) -> Path:
        """Remember ``out`` and its files now, so that ``files`` lists only the ones this run wrote."""
        self.out = Path(out)
        self._before = _files_below(self.out)
        return self.out

    @property
    def warnings(self) -> list[str]:
        """Every warning printed during this command (see :func:`print_warning`)."""
        return list(PRINTED_WARNINGS)

    @contextlib.contextmanager
    def collecting_warnings(self):
        """Print every warning raised inside, repeated ones too, through :func:`print_warning` (so the
        summary counts it).

        The caller's filters stay in force, so ``tactilab --strict`` still turns plausibility warnings
        into errors.
        """
        with warnings.catch_warnings():
            warnings.showwarning = lambda message, *_, **__: print_warning(self.command, message)
            errors = [f for f in warnings.filters if f[0] == "error"]
            warnings.simplefilter("always", UserWarning)  # every run reports its own, repeated or not
            warnings.simplefilter("always", RuntimeWarning)
            for _, message, category, module, lineno in reversed(errors):  # keep --strict's errors on top
                warnings.filterwarnings("error", message.pattern if message else "", category,
                                        module.pattern if module else "", lineno)
            yield

    def as_dict(self) -> dict:
        """The summary as a JSON-ready dict."""
        if self.out is not None:
            after = _files_below(self.out)
            self.files = [p for p, t in after.items() if self._before.get(p) != t]
        return {"command": self.command, "computed": self.computed, "method": self.method,
                "error_estimate": self.error_estimate, "dropped": self.dropped, "warnings": self.warnings,
                "out": None if self.out is None else str(self.out), "files": self.files, **self.data}

    def emit(self, as_json: bool = False) -> None:
        """Print the summary block (or, with ``as_json``, one JSON object and nothing else) on stdout."""
        d = self.as_dict()
        if as_json:
            print(json.dumps(d, default=_json_default))
            return
        print(f"--- tactilab {self.command}: summary ---")
        for line in self.computed:
            print(f"computed: {line}")
        print(f"method: {self.method or 'n/a'}")
        print(f"error estimate: {self.error_estimate}")
        print("dropped: " + ("; ".join(self.dropped) if self.dropped else "nothing"))
        print(f"warnings: {len(self.warnings)}" + "".join(f"\n  - {w}" for w in self.warnings))
        if self.out is not None:
            names = [str(Path(p).relative_to(self.out)) for p in d["files"]]
            print(f"files: {self.out}/ ({', '.join(names) if names else 'none written'})")
        else:
            print("files: none (printed only)")


def _json_default(value):
    import numpy as np

    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


@contextlib.contextmanager
def renamed(mapping: dict[str, str]):
    """Re-word a library error that names a parameter (``max_steps: ...; give max_steps at most N``) so it
    names the command-line option that sets it (``--max-steps``)."""
    try:
        yield
    except ValueError as exc:
        text = str(exc)
        for parameter, option in mapping.items():
            if text.startswith(parameter + ":"):
                rest = text[len(parameter):].replace(f"give {parameter} at most", f"give {option} at most")
                raise ValueError(option + rest) from None
        raise


def check_hypothesis(text: str, option: str):
    """Parse a receptor hypothesis (``zx@1mm``) given on the command line; an error names the option.

    Returns the parsed ``tactilab.forward.ReceptorHypothesis``; on bad input the library's own
    message follows the option and the value.
    """
    from tactilab.forward import ReceptorHypothesis

    try:
        return ReceptorHypothesis.parse(text)
    except ValueError as exc:
        raise ValueError(f"{option} {text!r}: {' '.join(str(exc).split())}") from None
