"""The ``tactilab`` command: parse, call, print.

Subcommands live one per module, ``tactilab/cli/cmd_<name>.py``. Each module defines

- ``NAME``: the subcommand word,
- ``HELP``: its one-line description (shown by ``tactilab --help``),
- ``add_arguments(parser)``: its arguments, with units in every help text,
- ``run(args) -> int``: the call into the library.

They are discovered here, so adding a command touches no shared file. User mistakes
(``ValueError`` -- pydantic's ``ValidationError`` included -- and ``OSError``) print one
line on stderr and exit with status 2; they never show a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
import warnings
from importlib import metadata
from types import ModuleType

from tactilab.core.outputs import printable

EXIT_USER_ERROR = 2
EXIT_INTERRUPTED = 130


class _Parser(argparse.ArgumentParser):
    """argparse with one-line usage errors (the usage block is one --help away)."""

    def error(self, message: str):  # noqa: D401 - argparse API
        hint = ""
        if "expected one argument" in message:
            hint = " (a value that starts with '-' needs '=', e.g. --depth=-1mm)"
        self.exit(EXIT_USER_ERROR, f"{self.prog}: error: {message}{hint}; see '{self.prog} --help'\n")


def _version() -> str:
    try:
        return metadata.version("tactilab")
    except metadata.PackageNotFoundError:  # running from a source tree without install
        return "0+unknown"


def _command_modules() -> list[ModuleType]:
    import tactilab.cli as package

    modules = []
    for info in pkgutil.iter_modules(package.__path__):
        if info.name.startswith("cmd_"):
            modules.append(importlib.import_module(f"tactilab.cli.{info.name}"))
    return sorted(modules, key=lambda m: m.NAME)


def build_parser() -> argparse.ArgumentParser:
    """Build the top-level parser with every discovered subcommand."""
    parser = _Parser(
        prog="tactilab",
        description=(
            "Touch science toolkit. Units: SI inside; files and options take explicit "
            "suffixes (e.g. 1.25mm, 20kPa, 5ms)."
        ),
    )
    parser.add_argument("--version", action="version", version=f"tactilab {_version()}")
    parser.add_argument("--strict", action="store_true",
                        help="treat implausible values (e.g. a 50 m grid spacing, a 1 Pa modulus) as errors")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", title="commands")
    for module in _command_modules():
        p = sub.add_parser(module.NAME, help=module.HELP, description=module.HELP)
        module.add_arguments(p)
        p.set_defaults(_run=module.run)
    return parser


def one_line(exc: BaseException) -> str:
    """Render an exception as a single line (pydantic errors have one line per field)."""
    errors = getattr(exc, "errors", None)
    if callable(errors):
        try:
            parts = []
            for err in errors():
                loc = ".".join(str(x) for x in err.get("loc", ()))
                msg = str(err.get("msg", "")).removeprefix("Value error, ")
                parts.append(f"{loc}: {msg}" if loc else msg)
            if parts:
                return "; ".join(parts)
        except (TypeError, AttributeError):
            pass
    text = " ".join(str(exc).split())
    if isinstance(exc, OSError) and exc.filename is not None and exc.strerror:
        text = f"{exc.strerror}: {exc.filename}"
    return printable(text) or type(exc).__name__  # a value quoted from a file never reaches the terminal raw


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script; returns the process exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "_run", None) is None:
        parser.print_help()
        return EXIT_USER_ERROR
    from tactilab.data_schemas.plausibility import PlausibilityWarning

    from .common import PRINTED_WARNINGS, print_warning

    def one_line_warning(message, category, filename, lineno, file=None, line=None):
        # users see one line per warning, never the warnings module's source line; each is counted
        print_warning(args.command, message)

    PRINTED_WARNINGS.clear()  # this command's summary counts this command's warnings
    with warnings.catch_warnings():
        warnings.showwarning = one_line_warning
        if args.strict:
            warnings.simplefilter("error", PlausibilityWarning)
        try:
            status = args._run(args)
        except KeyboardInterrupt:
            print("tactilab: interrupted", file=sys.stderr)
            return EXIT_INTERRUPTED
        except (ValueError, OSError, PlausibilityWarning) as exc:
            print(f"tactilab {args.command}: error: {one_line(exc)}", file=sys.stderr)
            return EXIT_USER_ERROR
    return int(status or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
