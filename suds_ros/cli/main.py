"""The ``suds`` command: simulate, inspect, identify, score, diagnose, monitor; model files; import tracked animals.

One parser (:func:`build_parser`) assembled from the command modules
(:mod:`~suds_ros.cli.simulate`, :mod:`~suds_ros.cli.inspect`,
:mod:`~suds_ros.cli.identify`, :mod:`~suds_ros.cli.diagnose`,
:mod:`~suds_ros.cli.monitor`, :mod:`~suds_ros.cli.model`,
:mod:`~suds_ros.cli.import_tracks`), each of which
registers its subcommands and a ``run(args) -> int``; and one error handler
(:func:`main`): a deliberate error (:class:`~suds_ros.core.errors.SudsError`,
or a command line argparse refuses) prints one ``ERROR: …`` line on stderr and
returns 2, never a traceback.  Options are never abbreviated: ``--model-o`` is
refused, not taken for ``--model-out``.
"""

from __future__ import annotations

import argparse
import sys
from typing import NoReturn, Sequence

from suds_ros.core.blas import pin_blas_threads
from suds_ros.core.errors import MISSING_JOINT_ROLES, MISSING_SYSTEM, SudsConfigError, SudsError

#: what the user can do about an error of a given code, in the words of this command line
HINTS = {
    MISSING_SYSTEM: "pass --system",
    MISSING_JOINT_ROLES: "pass --actuated (or --passive)",
}


class UsageError(SudsConfigError):
    """The command line itself is wrong (unknown option, missing argument, bad value)."""

    code = "usage"


class _Parser(argparse.ArgumentParser):
    """An argument parser that never abbreviates options and reports errors as :class:`UsageError`.

    Subcommand parsers are built with the same class, so the rules hold for all of them.
    """

    def __init__(self, *args: object, **kwargs: object) -> None:
        kwargs["allow_abbrev"] = False
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]

    def error(self, message: str) -> NoReturn:
        raise UsageError(f"{self.prog}: {message} (see `{self.prog} --help`)")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``suds``."""
    from suds_ros.cli import diagnose, identify, import_tracks, inspect, model, monitor, optimize, simulate

    parser = _Parser(
        prog="suds",
        description="Identify shape-underactuated dissipative systems (SUDS) from their motion, "
        "and diagnose where a simulator disagrees with a recording.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    simulate.add_parser(sub)
    inspect.add_parsers(sub)
    identify.add_parser(sub)
    diagnose.add_parser(sub)
    monitor.add_parser(sub)
    model.add_parser(sub)
    import_tracks.add_parser(sub)
    optimize.add_parser(sub)
    return parser


def error_line(exc: SudsError) -> str:
    """The one line printed for ``exc``: its first line, plus the command line's hint for its code."""
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    hint = HINTS.get(exc.code)
    return f"ERROR: {text}; {hint}" if hint else f"ERROR: {text}"


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``suds``; returns the process exit code.

    BLAS is limited to ``SUDS_BLAS_THREADS`` threads (default 1) first: see :mod:`suds_ros.core.blas`.
    """
    try:
        pin_blas_threads()
        args = build_parser().parse_args(argv)
        return int(args.func(args))
    except SudsError as exc:
        print(error_line(exc), file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("ERROR: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader went away (`suds info bag | head`): nothing more to say
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit
        return 0


if __name__ == "__main__":
    sys.exit(main())
