"""The ``kgarment`` command line: a thin layer over the library.

One module per command group (``inputs``: motions, garments, render, clutches, examples;
``simulate``; ``design``: design, evaluate, demo; ``plan``; ``fabricate``; ``reproduce``;
``studio``; ``sweep``) and ``common`` for the shared arguments.  Each command parses its flags,
calls the library and prints; a user error (:class:`~kgarment.errors.KgarmentError`)
prints one line and exits with status 2.  Commands import the pipeline stages they use
when they run, so ``kgarment --help`` starts without loading torch.
"""

from __future__ import annotations

import argparse
import logging
import sys

from kgarment import __version__
from kgarment.cli import design, fabricate, inputs, plan, reproduce, simulate, studio, sweep
from kgarment.errors import KgarmentError

GROUPS = (inputs, simulate, design, plan, fabricate, studio, reproduce, sweep)
QUIET_SOLVER = ("design", "demo", "reproduce", "plan", "sizes")  # the progress bar says enough


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors (the field, what is allowed; exit status 2), like
    every other user error of kgarment, instead of the usage block."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    ap = Parser(prog="kgarment", description="Design active kinesthetic garments with "
                                                              "electrostatic clutches.")
    ap.add_argument("--version", action="version", version=f"kgarment {__version__}")
    ap.add_argument("-v", "--verbose", action="count", default=0, help="more log output (-vv for debug)")
    ap.add_argument("-q", "--quiet", action="store_true", help="only warnings and errors")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND")
    for group in GROUPS:
        group.add_parsers(sub)
    return ap


def main(argv=None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    level = logging.WARNING if args.quiet else (logging.DEBUG if args.verbose > 1 else logging.INFO)
    logging.basicConfig(level=level, format="%(message)s")
    for noisy in ("anny", "warp", "matplotlib", "PIL", "ezdxf"):
        logging.getLogger(noisy).setLevel(max(level, logging.WARNING))
    if args.verbose == 0 and getattr(args, "command", None) in QUIET_SOLVER:
        logging.getLogger("kgarment.sim").setLevel(logging.WARNING)
    if not getattr(args, "command", None):
        ap.print_help()
        return 2
    try:
        return args.func(args)
    except KgarmentError as exc:
        print(f"kgarment: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into head and the like
        return 0
    except OSError as exc:
        if exc.filename is None:  # not about a file the user named: a defect, with its traceback
            raise
        print(f"kgarment: error: {exc.filename}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("kgarment: interrupted", file=sys.stderr)
        return 130
