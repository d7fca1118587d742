"""Console set-up (fxcontact.console): compiler log only when verbose, messages on rank 0 only
(rank-local ones on every rank, prefixed), quiet runs without progress bar."""

import io
import logging

import pytest
from mpi4py import MPI

from fxcontact import console


@pytest.fixture
def restore_logging():
    """Keep the test's logging changes out of the other tests."""
    root = logging.getLogger()
    saved = (list(root.handlers), list(root.filters), root.level,
             {n: logging.getLogger(n).level for n in ("fxcontact", *console.THIRD_PARTY)})
    yield
    for h in list(root.handlers):
        root.removeHandler(h)
    for f in list(root.filters):
        root.removeFilter(f)
    handlers, filters, level, levels = saved
    for h in handlers:
        root.addHandler(h)
    for f in filters:
        root.addFilter(f)
    root.setLevel(level)
    for n, lv in levels.items():
        logging.getLogger(n).setLevel(lv)
    logging.captureWarnings(False)
    console._state["progress"] = True


def _emit(verbose, quiet):
    """Log like the JIT build (INFO on the root logger, with the root level lowered as cffi does),
    like the library (INFO/WARNING/DEBUG on fxcontact loggers) and a rank-local warning."""
    out = io.StringIO()
    console.configure_logging(verbose=verbose, quiet=quiet, stream=out)
    root = logging.getLogger()
    old = root.level
    root.setLevel(logging.INFO)  # what distutils.log.set_verbosity(1) does during the build
    root.info("x86_64-linux-gnu-gcc -shared build line")
    root.setLevel(old)
    lib = logging.getLogger("fxcontact.simulation")
    lib.info("run summary")
    lib.debug("debug detail")
    lib.warning("collective warning")
    logging.getLogger("fxcontact.tools.faceted").warning("local warning", extra=console.ALL_RANKS)
    logging.getLogger("ffcx").info("Calling JIT C compiler")
    return out.getvalue()


@pytest.mark.parametrize("mode", ["default", "verbose", "quiet"])
def test_console_levels_and_ranks(restore_logging, mode):
    comm = MPI.COMM_WORLD
    text = _emit(mode == "verbose", mode == "quiet")
    rank0 = comm.rank == 0
    assert ("gcc -shared" in text) == (mode == "verbose" and rank0)
    assert ("Calling JIT" in text) == (mode == "verbose" and rank0)
    assert ("run summary" in text) == (mode != "quiet" and rank0)
    assert ("debug detail" in text) == (mode == "verbose" and rank0)
    assert ("collective warning" in text) == rank0  # once, not once per rank
    assert text.count("local warning") == 1  # every rank that has one
    if comm.size > 1 and not rank0:
        assert f"[rank {comm.rank}] WARNING fxcontact.tools.faceted: local warning" in text
    else:
        assert "[rank" not in text
    assert console.progress_enabled() == (mode != "quiet")


def test_console_configure_twice_keeps_one_handler(restore_logging):
    out = io.StringIO()
    console.configure_logging(stream=out)
    console.configure_logging(stream=out)
    root = logging.getLogger()
    assert sum(h.get_name() == console._HANDLER_NAME for h in root.handlers) == 1
    assert sum(isinstance(f, console._RootBelowWarning) for f in root.filters) == 1
    logging.getLogger("fxcontact").warning("once")
    assert out.getvalue().count("once") == (1 if MPI.COMM_WORLD.rank == 0 else 0)


def test_console_arguments(restore_logging):
    import argparse

    ap = console.add_verbosity_arguments(argparse.ArgumentParser())
    a = ap.parse_args(["--quiet"])
    assert a.quiet and not a.verbose
    assert ap.parse_args(["-v"]).verbose
    with pytest.raises(SystemExit):  # mutually exclusive
        ap.parse_args(["-v", "-q"])
    with pytest.raises(ValueError, match="exclusive"):
        console.configure_logging(verbose=True, quiet=True)
