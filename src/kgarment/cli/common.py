"""What the commands share: the problem argument and its overrides, the device, the
activation syntax, the design progress bar and output checks."""

from __future__ import annotations

import argparse
import math
from contextlib import contextmanager

from kgarment import constants as C
from kgarment.case.keys import RHO, Kind, StateKey, state_column
from kgarment.errors import KgarmentError

DEFAULT_PROBLEM_HELP = "problem file (TOML); default: the built-in three-motion shirt"


def integer(low: int | None = None, high: int | None = None):
    """An argparse type: an integer (written as one: not 2.5, not true) in [low, high]."""

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if (low is not None and v < low) or (high is not None and v > high):
            raise argparse.ArgumentTypeError(f"{v} is outside [{'' if low is None else low}, "
                                             f"{'' if high is None else high}]")
        return v

    return parse


def number(low: float | None = None, high: float | None = None, low_open: bool = False):
    """An argparse type: a finite number in [low, high] (``low_open``: (low, high])."""

    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        too_low = low is not None and (v <= low if low_open else v < low)
        if not math.isfinite(v) or too_low or (high is not None and v > high):
            lo = "" if low is None else f"{'(' if low_open else '['}{low:g}"
            raise argparse.ArgumentTypeError(f"{text} is outside {lo or '('}, {'' if high is None else f'{high:g}'}]"
                                             if math.isfinite(v) else f"{text} is not a finite number")
        return v

    return parse


SUBDIVISION = integer(min(C.SUBDIVISIONS), max(C.SUBDIVISIONS))
MAX_ITERATIONS = integer(*C.DESIGN_RANGES["max_iterations"])
FRAMES = integer(1, 200)  # evaluate --path: frames from rest to the target pose


def add_problem(sp, help: str = DEFAULT_PROBLEM_HELP) -> None:
    sp.add_argument("problem", nargs="?", help=help)


def device(text: str) -> str:
    """A torch device this machine has: cpu, cuda, cuda:N, mps (checked before any work)."""
    if text == "cpu":
        return text
    import torch

    try:
        dev = torch.device(text)
    except (RuntimeError, ValueError):
        raise argparse.ArgumentTypeError(f"{text!r} is not a torch device; allowed: cpu, cuda, cuda:N, mps") from None
    if dev.type == "cuda" and (not torch.cuda.is_available()
                               or (dev.index is not None and dev.index >= torch.cuda.device_count())):
        n = torch.cuda.device_count() if torch.cuda.is_available() else 0
        raise argparse.ArgumentTypeError(f"{text}: this machine has {n} CUDA device(s) usable by torch"
                                         + ("" if n else "; use cpu"))
    if dev.type == "mps" and not torch.backends.mps.is_available():
        raise argparse.ArgumentTypeError(f"{text}: no MPS device here; use cpu")
    if dev.type not in ("cpu", "cuda", "mps"):
        raise argparse.ArgumentTypeError(f"{text}: kgarment runs on cpu, cuda or mps")
    return text


def add_device(sp) -> None:
    sp.add_argument("--device", default="cpu", type=device, help="torch device for numerical work: cpu (default), "
                    "cuda, cuda:N or mps")


def add_overrides(sp, *, motion: bool = True, garment: bool = True, subdivision: bool = True,
                  materials: bool = False, solver: bool = False, max_iterations: bool = False,
                  clutch: bool = False) -> None:
    """Flags that override fields of the problem file (validated like the file's)."""
    if motion:
        sp.add_argument("--motion", action="append", help="motion (repeatable); default: the problem's motions")
    if garment:
        sp.add_argument("--garment", help="garment template name (overrides the problem's)")
    if subdivision:
        sp.add_argument("--subdivision", type=SUBDIVISION, help="garment subdivision level 0-3 (resolution)")
    if materials:
        sp.add_argument("--preset", help="material preset: paper or reference (default: the problem's [materials])")
    if solver:
        sp.add_argument("--solver", help="solver: newton or lbfgs (default: the problem's [solver] method)")
        sp.add_argument("--tol", type=number(*C.SOLVER_RANGES["tol"]), help="solver tolerance (scaled force residual; default: the problem's "
                                                  "[solver] tol, capped at the evaluation tolerance 1e-4)")
    if max_iterations:
        sp.add_argument("--max-iterations", type=MAX_ITERATIONS, help="stop after this many iterations")
        sp.add_argument("--refine", action="store_true", help="coarse-to-fine: evolve the design at subdivision 0 "
                        "(and each level up to the garment's, in RUN/level<L>) and finish at the garment's level "
                        "(the problem's [design] levels otherwise)")
    if clutch:
        add_clutch_model(sp)
        add_skin_friction(sp)


def add_skin_friction(sp) -> None:
    """--skin-friction (the problem's [materials] skin_friction, kgarment.sim.friction)."""
    sp.add_argument("--skin-friction", type=number(0.0, C.FRICTION_MAX), metavar="MU",
                    help="friction coefficient between skin and garment (0: the paper's frictionless body; "
                    "cloth on skin is about 0.3-0.6; default: the problem's [materials] skin_friction, else 0)")


def add_clutch_model(sp, buckle_default: str = "the problem's [clutches] buckle",
                     model_default: str = "the problem's [clutches] model") -> None:
    """--clutch-model, --holding-force, --buckle and --channel (the [clutches] hardware, kgarment.sim.slip;
    ``buckle_default`` and ``model_default``: what --help says happens without them)."""
    sp.add_argument("--clutch-model", choices=C.CLUTCH_MODELS, help="locked: an ON clutch never slips (the "
                    "paper's model); slip: it holds up to its holding force and slides at it beyond; cable: like slip, "
                    "but the strip carries one pull-only force between its ends (its parts may stretch while it is "
                    f"shortened on the whole) (default: {model_default})")
    sp.add_argument("--holding-force", type=number(*C.CLUTCH_RANGES["holding_force"]), metavar="N",
                    help="newtons every clutch holds before it slides (implies --clutch-model slip unless cable; default: "
                    f"the problem's, else {C.HOLDING_STRESS / 1e4:g} N/cm^2 of strip)")
    sp.add_argument("--buckle", action=argparse.BooleanOptionalAction, default=None,
                    help="ON clutch strips buckle: they take no compression (--no-buckle: they resist it as stiffly "
                    f"as tension, the paper's model; default: {buckle_default})")
    sp.add_argument("--channel", action=argparse.BooleanOptionalAction, default=None,
                    help="each clutch runs in a channel sewn along it to the garment, its centre line held as "
                    "stiffly as reinforced fabric (--no-channel: snapped on at its ends only, the paper's build, "
                    "where a strip pulled over a bent elbow can roll off sideways; default: the problem's "
                    "[clutches] channel)")


def overrides(args) -> dict:
    """The problem overrides given on the command line (``kgarment.problem.override``)."""
    return {"motions": getattr(args, "motion", None), "template": getattr(args, "garment", None),
            "subdivision": getattr(args, "subdivision", None), "preset": getattr(args, "preset", None),
            "method": getattr(args, "solver", None), "tol": getattr(args, "tol", None),
            "max_iterations": getattr(args, "max_iterations", None),
            "clutch_model": getattr(args, "clutch_model", None), "holding_force": getattr(args, "holding_force", None),
            "buckle": getattr(args, "buckle", None), "channel": getattr(args, "channel", None),
            "refine": getattr(args, "refine", False),
            "friction": getattr(args, "skin_friction", None)}


def load(args):
    """The problem of the command: its file (or the built-in default) with the flags'
    overrides."""
    from kgarment.problem import Problem, load_problem, override

    p = load_problem(args.problem) if getattr(args, "problem", None) else Problem()
    return override(p, **overrides(args))


def parse_phenotype(text: str, base):
    """'weight=0.8,height=0.3' -> ``base`` (a Phenotype) with those fields replaced; one-line
    errors naming the field and what is allowed."""
    import dataclasses

    from kgarment.body import Phenotype

    fields = dataclasses.asdict(base)
    items = [x.strip() for x in text.split(",") if x.strip()]
    if not items:
        raise KgarmentError(f"--phenotype {text!r} changes nothing; give FIELD=VALUE,..., e.g. weight=0.8")
    given = [i.partition("=")[0].strip() for i in items]
    twice = next((k for k in given if given.count(k) > 1), None)
    if twice is not None:
        raise KgarmentError(f"--phenotype {text!r} gives {twice} more than once")
    for item in items:
        key, sep, value = item.partition("=")
        try:
            fields[key.strip()] = float(value) if sep else None
        except ValueError:
            raise KgarmentError(f"--phenotype {item!r}: {value!r} is not a number in [0, 1]") from None
        if not sep:
            raise KgarmentError(f"--phenotype {item!r}: give FIELD=VALUE, e.g. weight=0.8")
    return Phenotype.from_dict(fields)


def parse_activation(text: str, n_clutches: int) -> tuple[float, ...]:
    """'on' (all 1), 'off' (all 0), or K comma-separated values in [0, 1] ('1,0,0.5')."""
    if text == "on":
        return (1.0,) * n_clutches
    if text == "off":
        return (0.0,) * n_clutches
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) != n_clutches or not all(0.0 <= v <= 1.0 for v in vals):
        raise KgarmentError(f"clutch activation {text!r}: give on, off, or {n_clutches} comma-separated values in [0, 1]")
    return vals


def rho_line(row: dict, motions) -> str:
    """One line for a metrics row: area, objective, rho ON/OFF per motion."""
    def col(m: str, kind: Kind) -> str:
        return state_column(RHO, StateKey.of(m, kind))

    rho = "  ".join(f"{m} {row.get(col(m, Kind.ON), row.get(col(m, Kind.NONE), float('nan'))):.2f}"
                    + (f"/{row[col(m, Kind.OFF)]:.2f}" if col(m, Kind.OFF) in row else "") for m in motions)
    return f"area {100 * row['area']:5.1f}%  objective {row['objective']:8.4f}  rho {rho}"


@contextmanager
def design_progress(total: int, start: int, motions, quiet: bool):
    """A progress bar over design iterations (lines where standard output is not a terminal:
    :mod:`kgarment.cli.progress`); yields ``update(state)`` for the driver."""
    import logging

    from rich.progress import TextColumn

    from kgarment.cli.progress import progress_bars

    log = logging.getLogger("kgarment")
    with progress_bars((TextColumn("[bold]it {task.completed:>3}"),),
                       lambda t: f"it {t['completed']:>3} of ~{t['total']}", quiet) as bar:
        task = bar.add_task("starting", total=total, completed=start)

        def update(st) -> None:
            row = st.metrics[-1]
            bar.update(task, completed=row["iteration"] + 1, description=rho_line(row, motions),
                       total=max(total, row["iteration"] + 2))
            if row["unconverged_states"]:
                log.warning("iteration %d: states not converged: %s", row["iteration"], row["unconverged_states"])

        yield update


def print_evaluation(res) -> None:
    """A design's evaluation (kgarment.design.DesignEvaluation) as tables on stdout."""
    w = max([6] + [len(r.state) for r in res.states])  # lock states: "lock:OTHER MOTION"
    print(f"{'motion':24s} {'state':{w}s} {'rho':>7s} {'E design (J)':>13s} {'E full (J)':>11s}")
    for r in res.states:
        flag = "" if r.converged else "  (NOT converged)"
        if r.from_path:
            flag += "  (the motion from rest ends here; " + ("the two starts did not converge)" if r.other_rho is None
                                                            else f"the two starts' equilibrium above it has rho "
                                                                 f"{r.other_rho:.3f})")
        elif r.multistable:
            flag += f"  (a second equilibrium of higher energy has rho {r.other_rho:.3f})"
        print(f"{r.motion:24s} {r.state:{w}s} {r.rho:7.3f} {r.energy:13.5g} {r.energy_full:11.5g}{flag}")
    print(f"reinforced area {100 * res.area:.1f}%; islands {res.islands} ({res.islands_with_clutches} counting "
          f"clutches as links); clutch ends on reinforcement {res.clutch_ends_supported}/{res.clutch_ends}")
    for name, w in (res.by_wearer or {}).items():
        print(f"  on {name}: {w['islands_with_clutches']} part(s) counting clutches as links, clutch ends on "
              f"reinforcement {w['clutch_ends_supported']}/{w['clutch_ends']}")
    if res.loads is not None:
        print("clutch loads (share of the ON - OFF garment energy with only that clutch ON, the share lost with "
              "only it OFF / tension all ON; * loaded: either >= 0.1):")
        print(res.loads.table())
        idle = res.loads.unloaded()
        if idle:
            print(f"clutches that carry no load in any motion: {', '.join(idle)}")
