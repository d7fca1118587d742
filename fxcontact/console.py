"""Console set-up for scripts: one progress bar, warnings once, the form compiler's log on demand.

Library modules only create their loggers (``logging.getLogger(__name__)``) and never configure
logging. A script (every demo) calls :func:`configure_logging` once, usually through
:func:`add_verbosity_arguments`::

    ap = argparse.ArgumentParser()
    add_verbosity_arguments(ap)          # --verbose / --quiet
    args = ap.parse_args()
    configure_logging(args.verbose, args.quiet)

What it does:

* **One handler** on the root logger (it replaces the bare handler that FFCx's
  ``logging.basicConfig()`` installs at import), writing through ``tqdm.write`` so that a message
  does not break the progress bar.
* **Rank 0 only.** Under MPI most messages are collective (every rank would print the same line),
  so records are printed on rank 0 only. A message that is genuinely rank-local (e.g. the Nagata
  projection fall-backs of one rank's nodes) is logged with ``extra=ALL_RANKS`` and is printed by
  every rank that emits it, prefixed with ``[rank r]``.
* **The form compiler's build log** (cffi compiles the generated C code through distutils, which
  logs every ``gcc`` command at INFO on the *root* logger) is dropped unless ``verbose``: a filter
  on the root logger keeps only its warnings and errors. Loggers of fxcontact are not affected.
* **Levels.** default: fxcontact INFO (set-up facts, a summary line per run), FFCx/UFL/dolfinx
  WARNING, progress bar on. ``verbose``: fxcontact DEBUG, FFCx/UFL/dolfinx INFO and the compiler
  log. ``quiet``: warnings and errors only, no progress bar.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import sys

from mpi4py import MPI
from tqdm import tqdm

__all__ = ["configure_logging", "add_verbosity_arguments", "case_parser", "parse_case",
           "progress_enabled", "ALL_RANKS", "RankFilter", "auto_on_off"]

#: ``extra=`` argument of a logging call whose message is rank-local (printed by every rank).
ALL_RANKS = {"all_ranks": True}

#: Third-party loggers whose INFO output is only shown with ``verbose``.
THIRD_PARTY = ("ffcx", "UFL", "ufl", "dolfinx", "numba", "matplotlib", "PIL", "py.warnings")

_HANDLER_NAME = "fxcontact-console"
_state = {"progress": True}


def progress_enabled() -> bool:
    """False after ``configure_logging(quiet=True)``: :class:`~fxcontact.Simulation` then shows no
    progress bar. True otherwise (also when logging was never configured)."""
    return _state["progress"]


class RankFilter(logging.Filter):
    """Pass every record on rank 0; on other ranks only records logged with ``extra=ALL_RANKS``.

    Also sets ``record.rank_prefix`` (``"[rank r] "`` off rank 0 in a parallel run, else ``""``)
    for the format string.
    """

    def __init__(self, comm: MPI.Comm = MPI.COMM_WORLD):
        super().__init__()
        self.rank = comm.rank
        self.size = comm.size

    def filter(self, record: logging.LogRecord) -> bool:
        record.rank_prefix = f"[rank {self.rank}] " if self.rank and self.size > 1 else ""
        return self.rank == 0 or bool(getattr(record, "all_ranks", False))


class _RootBelowWarning(logging.Filter):
    """Filter on the root logger itself: drops the INFO/DEBUG records *created* on the root logger
    (the distutils build log of the JIT compiler); records of named loggers are not seen here."""

    def filter(self, record: logging.LogRecord) -> bool:
        return record.levelno >= logging.WARNING


class _TqdmHandler(logging.StreamHandler):
    """Stream handler that prints through ``tqdm.write`` (the bar is cleared and redrawn)."""

    def emit(self, record: logging.LogRecord):
        try:
            msg = self.format(record)
            try:
                tqdm.write(msg, file=self.stream)
            except ImportError:  # pragma: no cover - tqdm is a dependency
                self.stream.write(msg + self.terminator)
            self.flush()
        except Exception:  # pragma: no cover - logging must not raise
            self.handleError(record)


def configure_logging(verbose: bool = False, quiet: bool = False, comm: MPI.Comm = MPI.COMM_WORLD,
                      stream=None) -> logging.Handler:
    """Set up the console of a script (call once, early; calling again replaces the set-up).

    Args:
        verbose: fxcontact DEBUG messages, FFCx/UFL/dolfinx INFO and the C compiler's build log.
        quiet: warnings and errors only, and no progress bar.
        comm: communicator whose rank 0 prints (others print only ``extra=ALL_RANKS`` records).
        stream: where to write (default ``sys.stderr``).
    Returns:
        the handler installed on the root logger.
    """
    if verbose and quiet:
        raise ValueError("verbose and quiet are exclusive: give at most one of them")
    root = logging.getLogger()
    # remove the bare handler of FFCx's logging.basicConfig() and our own earlier set-up
    for h in list(root.handlers):
        if (h.get_name() == _HANDLER_NAME or (type(h) is logging.StreamHandler
                                              and getattr(h, "stream", None) is sys.stderr)):
            root.removeHandler(h)
    for f in list(root.filters):
        if isinstance(f, _RootBelowWarning):
            root.removeFilter(f)
    handler = _TqdmHandler(stream if stream is not None else sys.stderr)
    handler.set_name(_HANDLER_NAME)
    handler.addFilter(RankFilter(comm))
    handler.setFormatter(logging.Formatter("%(rank_prefix)s%(levelname)s %(name)s: %(message)s"))
    root.addHandler(handler)
    root.setLevel(logging.WARNING)
    if not verbose:
        root.addFilter(_RootBelowWarning())
    logging.captureWarnings(True)  # Python warnings go through the same (rank-0) handler

    if quiet:
        own, other = logging.WARNING, logging.WARNING
    elif verbose:
        own, other = logging.DEBUG, logging.INFO
    else:
        own, other = logging.INFO, logging.WARNING
    logging.getLogger("fxcontact").setLevel(own)
    for name in THIRD_PARTY:
        logging.getLogger(name).setLevel(logging.WARNING if name == "py.warnings" else other)
    _state["progress"] = not quiet
    return handler


def auto_on_off(value: str):
    """argparse ``type=`` for a command-line switch ``auto|on|off``: ``"auto"``, True or False
    (e.g. ``SolverOptions.active_set_prediction``)."""
    v = str(value).strip().lower()
    table = {"auto": "auto", "on": True, "off": False}
    if v not in table:
        raise argparse.ArgumentTypeError(f"expected auto, on or off, got {value!r}")
    return table[v]


def add_verbosity_arguments(parser):
    """Add the mutually exclusive ``--verbose`` / ``--quiet`` flags to an argparse parser."""
    g = parser.add_mutually_exclusive_group()
    g.add_argument("-v", "--verbose", action="store_true",
                   help="debug messages and the form compiler's build log")
    g.add_argument("-q", "--quiet", action="store_true",
                   help="warnings and errors only, no progress bar")
    return parser


#: argparse types of the annotations of a process case's fields
def on_off(value: str) -> bool:
    """argparse ``type=`` for a boolean field of a case: ``on|off`` (or true/false, 1/0)."""
    v = str(value).strip().lower()
    if v in ("on", "true", "1"):
        return True
    if v in ("off", "false", "0"):
        return False
    raise argparse.ArgumentTypeError(f"expected on or off, got {value!r}")


_CASE_TYPES = {"float": float, "Optional[float]": float, "int": int, "str": str,
               "bool": on_off}

#: annotations of the fields that have no text form (a case's penalty and friction objects):
#: the options named after their former fields give them
_NO_TEXT = ("Penalty", "fx.Penalty", "Friction")


def _former_options(case_type) -> dict:
    """``{option: (argparse type, help)}`` of the former fields of a case's penalty and
    friction (``case_type.FORMER``, :mod:`fxcontact.processes.contact_laws`)."""
    out = {}
    for spec in getattr(case_type, "FORMER", ()):
        for name, default in spec.defaults.items():
            f = case_type.__dataclass_fields__.get(name)
            kind = str(f.type) if f is not None and name != spec.field else "str"
            if kind.startswith("InitVar[") and kind.endswith("]"):
                kind = kind[len("InitVar["):-1]
            out[name] = (_CASE_TYPES.get(kind, str),
                         f"sets {spec.field} (its former spelling; default {default!r})")
    return out


def case_parser(case_type, description: str, output_dir: str):
    """An argparse parser for a process demo: ``--quick`` and one ``--<field>`` per field of
    the case (a dataclass such as :class:`fxcontact.processes.FlatRollingCase`), typed from the
    field's annotation (``auto|on|off`` for an ``object`` field whose default is ``"auto"``,
    ``on|off`` for a ``bool``), the case's ``penalty`` and ``friction`` objects through the
    options named after their former fields (``--mu``, ``--main_friction "norton,0.5,0.15"``,
    ``--gap_stiffness``), ``--output-dir`` and ``--verbose``/``--quiet``. Add the demo's own
    options, then :func:`parse_case`."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--quick", action="store_true",
                        help="the reduced size of the tests (the case's quick())")
    for f in dataclasses.fields(case_type):
        if str(f.type) in _NO_TEXT:
            continue
        auto = f.default == "auto" and str(f.type) == "object"     # "auto", True or False
        conv = auto_on_off if auto else _CASE_TYPES.get(str(f.type), str)
        parser.add_argument(f"--{f.name}", type=conv, help=f"default {f.default!r}")
    for name, (conv, text) in _former_options(case_type).items():
        parser.add_argument(f"--{name}", type=conv, help=text)
    parser.add_argument("--output-dir", dest="output_dir", default=output_dir,
                        help=f"where the results go (default {output_dir})")
    add_verbosity_arguments(parser)
    return parser


def parse_case(parser, case_type, argv=None):
    """Parse the command line of :func:`case_parser`, configure the console
    (:func:`configure_logging`) and return ``(case, args)``: the default case (its ``quick()``
    with ``--quick``) with the fields given on the command line (an option named after a former
    field sets the new one: the case's ``with_options``)."""
    args = parser.parse_args(argv)
    configure_logging(verbose=args.verbose, quiet=args.quiet)
    case = case_type().quick() if args.quick else case_type()
    names = [f.name for f in dataclasses.fields(case_type)] + list(_former_options(case_type))
    given = {k: getattr(args, k) for k in names if getattr(args, k, None) is not None}
    if hasattr(case, "with_options"):
        return case.with_options(**given), args
    return dataclasses.replace(case, **given), args
