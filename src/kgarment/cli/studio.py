"""``kgarment studio``: the interactive design page (viser) on a problem, run or session."""

from __future__ import annotations

import sys
import time

from kgarment.cli.common import add_device, add_overrides, add_problem, integer, overrides
from kgarment.errors import KgarmentError


def is_loopback(host: str) -> bool:
    """Whether ``host`` names this machine only (localhost, 127.0.0.0/8, ::1)."""
    import ipaddress

    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def cmd_studio(args) -> int:
    from kgarment.io import check_output_folder

    remote = not is_loopback(args.host)
    if remote and not args.allow_remote:
        raise KgarmentError(f"--host {args.host} would serve the studio to other machines over plain HTTP, its token "
                            "readable on the network (anyone who sees it can edit and run designs and write files "
                            f"under {args.runs}); add --allow-remote to do it anyway")
    check_output_folder(args.runs, "--runs")  # where the page writes: checked before it serves
    if args.session:
        check_output_folder(args.session, "--session")
    try:
        import viser  # noqa: F401
    except ImportError:
        raise KgarmentError("the studio needs viser: pip install -e '.[studio]'") from None
    from kgarment.studio import Studio, read_source

    opened = read_source(args.problem).with_overrides(**overrides(args))
    if not args.quiet:
        print(opened.problem.describe())
    studio = Studio(opened, host=args.host, port=args.port, session=args.session, runs=args.runs, device=args.device)
    if remote:
        print(f"kgarment studio: WARNING: serving on {args.host} over plain HTTP; anyone who sees the URL's token "
              f"on the network can use the studio on port {studio.server.get_port()}", file=sys.stderr)
    if studio.server.get_port() != args.port:
        print(f"kgarment studio: port {args.port} is taken; serving on port {studio.server.get_port()} instead")
    try:  # from the line that tells the URL on: a Ctrl-C right after it (a script, a test) stops cleanly
        print(f"kgarment studio: open {studio.url} in a browser (Ctrl-C stops the server)", flush=True)
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        if studio.state.dirty:
            print("kgarment studio: stopped with unsaved changes")
        return 0
    finally:
        studio.stop()


def add_parsers(sub) -> None:
    sp = sub.add_parser("studio", help="interactive design page in the browser: view, place clutches, paint, "
                        "simulate, optimise (viser)")
    add_problem(sp, "problem file, design run folder or studio session folder; default: the three-motion shirt")
    add_device(sp)
    add_overrides(sp)
    sp.description = ("Serve the studio page for PROBLEM (a problem file), RUN (a design run folder) or a studio "
                      "session folder; without one, the built-in three-motion shirt. The URL it prints carries a "
                      "session token, new at every start (http://127.0.0.1:PORT/?token=...): only the studio's own "
                      "page, opened from that URL, may connect; another web page (a foreign Origin) or a connection "
                      "without the token is refused. Files typed into the page are read only under --runs, the "
                      "folder of PROBLEM/RUN/SESSION and --session.")
    sp.add_argument("--host", default="127.0.0.1", help="address to serve on (default 127.0.0.1: this machine only; "
                    "any other needs --allow-remote)")
    sp.add_argument("--allow-remote", action="store_true", help="allow a --host that other machines reach (plain "
                    "HTTP: anyone who sees the URL's token on the network can use the studio)")
    sp.add_argument("--port", type=integer(1, 65535), default=8080, help="port (default 8080)")
    sp.add_argument("--session", help="folder that Save writes the session to (default: the opened session)")
    sp.add_argument("--runs", default="runs/studio", help="the one folder the page writes into (default "
                    "runs/studio): optimisation run folders, exports (RUNS/exports) and sessions saved under a "
                    "new name (RUNS/sessions); the page names files, never folders elsewhere")
    sp.set_defaults(func=cmd_studio)
