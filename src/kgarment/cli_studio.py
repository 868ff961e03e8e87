"""``kgarment studio``: the interactive design page (viser) on a problem, run or session."""

from __future__ import annotations

import dataclasses
import logging
import time

from kgarment.errors import KgarmentError, unknown

log = logging.getLogger("kgarment")


def _opened(args):
    """The source to open, with the command line's overrides applied to a problem file."""
    from kgarment.studio.session import read_source

    opened = read_source(args.problem)
    p = opened.problem
    if args.motion:
        lib = p.library()
        for m in args.motion:
            lib.get(m)
        p = dataclasses.replace(p, motions=tuple(args.motion))
    g = p.garment
    if args.garment:
        from kgarment.garment import template_names

        if args.garment not in template_names():
            raise unknown("garment", args.garment, template_names())
        g = dataclasses.replace(g, template=args.garment, mask=None)
    if args.subdivision is not None:
        g = dataclasses.replace(g, subdivision=args.subdivision)
    if g != p.garment and opened.kind in ("session", "run") and (opened.design is not None or opened.attached is not None):
        raise KgarmentError(f"--garment/--subdivision cannot change the garment of a {opened.kind}: its design "
                            "and attachments are per face; open its problem.toml instead")
    opened.problem = dataclasses.replace(p, garment=g)
    return opened


def cmd_studio(args) -> int:
    try:
        import viser  # noqa: F401
    except ImportError:
        raise KgarmentError("the studio needs viser: pip install -e '.[studio]'") from None
    from kgarment.studio.app import Studio

    opened = _opened(args)
    print(opened.problem.describe())
    studio = Studio(opened, host=args.host, port=args.port, session=args.session, runs=args.runs, device=args.device)
    print(f"kgarment studio: open {studio.url} in a browser (Ctrl-C stops the server)")
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        if studio.state.dirty:
            print("kgarment studio: stopped with unsaved changes")
        return 0
    finally:
        studio.stop()


def add_parser(sub, common) -> None:
    sp = sub.add_parser("studio", help="interactive design page in the browser: view, place clutches, paint, "
                        "simulate, optimise (viser)")
    common(sp)
    for action in sp._actions:  # the shared positional also takes runs and sessions here
        if action.dest == "problem":
            action.help = "problem file, design run folder or studio session folder; default: the three-motion shirt"
    sp.description = ("Serve the studio page for PROBLEM (a problem file), RUN (a design run folder) or a studio "
                      "session folder; without one, the built-in three-motion shirt.")
    sp.add_argument("--host", default="127.0.0.1", help="address to serve on (default 127.0.0.1: this machine only)")
    sp.add_argument("--port", type=int, default=8080, help="port (default 8080)")
    sp.add_argument("--session", help="folder that Save writes the session to (default: the opened session)")
    sp.add_argument("--runs", default="runs/studio", help="where optimisations started from the page write their "
                    "run folders (default runs/studio)")
    sp.add_argument("--motion", action="append", help="motion (repeatable); default: the problem's motions")
    sp.add_argument("--garment", help="garment template name (overrides the problem's)")
    sp.add_argument("--subdivision", type=int, choices=(0, 1, 2, 3), help="garment subdivision level")
    sp.set_defaults(func=cmd_studio)
