"""The command line run inside the test process.

A ``python -m kgarment.cli`` subprocess pays for importing torch, numba's kernels and the
body again (3-8 s of CPU each on 2 cores; the suite ran ~60 of them).  ``run_cli`` calls
the same entry point, :func:`kgarment.cli.main`, in this process: the same argument
parsing, the same exit statuses (argparse's ``SystemExit`` included), stdout and stderr
captured, the log records of the run on stderr as the command line shows them.  Tests that
need a process of their own (Ctrl-C, a server, a fresh interpreter) still start one.
"""

from __future__ import annotations

import contextlib
import io
import logging
import os
from pathlib import Path

from kgarment.cli import main

# the loggers main() sets a level on (restored after each call, as a new process starts afresh)
_LOGGERS = ("", "kgarment", "kgarment.sim", "anny", "warp", "matplotlib", "PIL", "ezdxf")


def run_cli(argv, cwd: str | os.PathLike | None = None) -> tuple[int, str, str]:
    """``kgarment ARGV`` run in ``cwd`` (default: here).  Returns (exit status, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    handler = logging.StreamHandler(err)
    handler.setFormatter(logging.Formatter("%(message)s"))
    levels = {name: logging.getLogger(name).level for name in _LOGGERS}
    root = logging.getLogger()
    root.addHandler(handler)
    here = Path.cwd()
    try:
        if cwd is not None:
            os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                rc = main([str(a) for a in argv])
            except SystemExit as e:  # argparse's errors, --help and --version
                rc = e.code if isinstance(e.code, int) else (0 if e.code is None else 2)
    finally:
        os.chdir(here)
        root.removeHandler(handler)
        for name, level in levels.items():
            logging.getLogger(name).setLevel(level)
    return rc, out.getvalue(), err.getvalue()
