"""What the wearer feels over the whole motion: quasi-static frames from rest to the target.

The paper measured force while the wearer performed each motion slowly (a strip on a load
cell in place of a clutch, force against motion progress).  :func:`path_forces` does the
same in simulation: the motion's bone rotations are scaled by ``t = 1/K, 2/K, ..., 1``
(:meth:`kgarment.body.Motion.at`: the skinning transforms are interpolated, not the
vertices), the body is posed in each frame, and the design's equilibrium is solved frame
after frame, ON (the motion's activation set) and OFF, from rest: each frame starts where
the path predicts it (:func:`predicted`, the secant predictor of path following: the last
equilibrium carried with the body -- moved as the skin-tight garment moves between the two
frames, :func:`carried` -- plus how the garment moved against the body over the step
before).  Per frame: the garment's total energy (J) and the tension in every clutch (N,
:func:`kgarment.sim.clutch_tensions`).

The rest pose (t = 0) is a frame too (:func:`rest_frames`): the lowest equilibrium from the
evaluator's starts -- solved first: the first frame starts from it -- and backwards from the
first frame.  The garment stores energy before
the motion begins: the attachment rings and the body's contact hold it stretched (on the
two-motion sleeve at subdivision 1, 11.7 J OFF at rest, about 8 J of it in the attachment
springs and 3 J in contact, against 13.0 J at the end of arm flexion).  The work the
wearer does against the garment over the motion, the motion being quasi-static and the
garment elastic, is therefore its energy at the target *less its energy at rest*
(``work_on_J``, ``work_off_J`` of :meth:`PathReport.summary`).

Equilibria of a sparse design on a frictionless body can switch from one frame to the next
(the garment settles elsewhere, or a warm start carried over a moving body ends tangled in
a high-energy one).  Where a state's energy drops by more than :data:`PATH_JUMP` from one
frame to the next while the motion goes on, the earlier frame is re-solved from the later
frame's equilibrium and from the evaluator's two starts, and the lowest-energy equilibrium
kept.  The last frame is the target
pose, where the one design evaluator's equilibrium (two starts) is known: where it has
less energy than the path's end, it replaces it and the frames before are re-solved
backwards from it while that lowers their energy.  The report lists every frame
re-solved.  With skin friction (``[materials] skin_friction``, :mod:`kgarment.sim.friction`)
none is: the state then depends on the path taken, not on which equilibrium stores least,
and the frames solved one after the other are that path.  Friction then holds each frame
where the frame before left the garment (:func:`held_at`, the state's ``anchor``), not at
the skin-tight garment: what slid beyond the skin's give stays slid, as Coulomb friction
keeps no memory of where the garment started, and what stuck keeps its offset, so that a
frame does not let the garment creep (the rest pose anchors at the skin-tight garment, and
so does the first frame where the rest pose did not converge).
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from kgarment.case.frames import REST, frame_motions
from kgarment.case.starts import MULTISTABLE
from kgarment.constants import PATH_FRAMES
from kgarment.errors import KgarmentError
from kgarment.io import time_left
from kgarment.sim import SimState, clutch_tensions, held_after
from kgarment.sim.slip import slides

log = logging.getLogger(__name__)
PATH_JUMP = 0.02   # a relative energy drop between frames counted as a switch of equilibrium
REST_STARTS = 2    # how the rest frame is solved (JSON "rest_starts"; 2: also backwards from the first frame)
STATES = ("on", "off")


@dataclass(frozen=True)
class PathFrame:
    """One frame of one motion in one state: t in (0, 1] (motion progress), energy_J (the
    garment's total energy), tension_N (K,) per clutch, converged, resolved (re-solved from
    the next frame's equilibrium)."""

    motion: str
    state: str
    t: float
    energy_J: float
    tension_N: tuple[float, ...]
    converged: bool
    resolved: bool = False

    def row(self, clutches) -> dict:
        return {"motion": self.motion, "state": self.state, "t": self.t, "energy_J": self.energy_J,
                "tension_N": dict(zip(clutches, self.tension_N)), "converged": self.converged,
                "resolved": self.resolved}


@dataclass(frozen=True)
class PathReport:
    """Frames of every motion, ON and OFF; clutches : clutch names in tension order;
    holding_N : ((motion, (K,) N), ...) the force each clutch holds in the motion's ON state
    with the slip model (:mod:`kgarment.sim.slip`), empty for locked clutches;  ends :
    {(motion, "on" | "off"): StateResult} the last frame's equilibria (the target pose
    reached from rest), for :meth:`kgarment.design.Evaluator.evaluate`'s ``known`` (not in
    the JSON)."""

    clutches: tuple[str, ...]
    frames: tuple[PathFrame, ...]
    holding_N: tuple[tuple[str, tuple[float, ...]], ...] = ()
    ends: dict = field(default_factory=dict, repr=False, compare=False)

    def slips(self) -> list[dict]:
        """Per motion and clutch that reaches its holding force ON: the first frame's
        progress ``t`` where it slides (tension at :data:`kgarment.constants.SLIPPING` of
        the holding force or more, :func:`kgarment.sim.slip.slides`) and the holding force (N)."""
        out = []
        for m, hold in self.holding_N:
            for k, c in enumerate(self.clutches):
                t = next((f.t for f in self.curve(m, "on") if slides(f.tension_N[k], hold[k])), None)
                if t is not None:
                    out.append({"motion": m, "clutch": c, "from_t": t, "holding_N": hold[k]})
        return out

    @property
    def motions(self) -> list[str]:
        return list(dict.fromkeys(f.motion for f in self.frames))

    def curve(self, motion: str, state: str) -> list[PathFrame]:
        return sorted((f for f in self.frames if f.motion == motion and f.state == state), key=lambda f: f.t)

    def summary(self) -> list[dict]:
        """Per motion and clutch: peak and mean tension ON and OFF (N; the mean over the
        frames after rest), and per motion the garment's energy at the target ON and OFF
        (J) and the work against it over the motion (J: the energy at the target less the
        energy at rest, where the report has the rest frame)."""
        out = []
        for m in self.motions:
            on, off = self.curve(m, "on"), self.curve(m, "off")
            for k, c in enumerate(self.clutches):
                t_on = np.array([f.tension_N[k] for f in on])
                t_off = np.array([f.tension_N[k] for f in off])
                out.append({"motion": m, "clutch": c, "peak_on_N": float(t_on.max()),
                            "mean_on_N": float(_moving(on, k).mean()), "peak_off_N": float(t_off.max()),
                            "mean_off_N": float(_moving(off, k).mean()), "work_on_J": self.work(m, "on"),
                            "work_off_J": self.work(m, "off"), "energy_on_J": on[-1].energy_J,
                            "energy_off_J": off[-1].energy_J})
        return out

    def work(self, motion: str, state: str) -> float:
        """The work over ``motion`` in ``state`` (J, :func:`work_from_rest`)."""
        return work_from_rest([(f.t, f.energy_J) for f in self.curve(motion, state)])

    def with_rest(self, frames) -> PathReport:
        """This report with its rest frames (t = 0) replaced by ``frames`` (:func:`rest_frames`)."""
        return PathReport(self.clutches, tuple(frames) + tuple(f for f in self.frames if f.t > 0.0), self.holding_N,
                          self.ends)

    @property
    def has_rest(self) -> bool:
        return any(f.t == 0.0 for f in self.frames)

    @classmethod
    def from_json(cls, doc: dict) -> PathReport:
        """The report of :meth:`to_json`'s ``doc`` (without ``ends``)."""
        clutches = tuple(doc["clutches"])
        frames = tuple(PathFrame(f["motion"], f["state"], float(f["t"]), float(f["energy_J"]),
                                 tuple(float(f["tension_N"][c]) for c in clutches), bool(f["converged"]),
                                 resolved=bool(f.get("resolved", False))) for f in doc["frames"])
        hold = tuple((m, tuple(float(h[c]) for c in clutches)) for m, h in doc.get("holding_N", {}).items())
        return cls(clutches, frames, hold)

    def resolved(self) -> list[PathFrame]:
        return [f for f in self.frames if f.resolved]

    def to_json(self) -> dict:
        out = {"clutches": list(self.clutches), "frames": [f.row(self.clutches) for f in self.frames],
               "summary": self.summary(), "resolved": [(f.motion, f.state, f.t) for f in self.resolved()]}
        if self.has_rest:
            out["rest_starts"] = REST_STARTS
        if self.holding_N:  # the slip model's
            out["holding_N"] = {m: dict(zip(self.clutches, h)) for m, h in self.holding_N}
            out["slips"] = self.slips()
        return out

    def table(self) -> str:
        """Per motion and frame: energy ON / OFF (J) and each clutch's tension ON (N)."""
        head = f"{'motion':22s} {'t':>5s} {'E on (J)':>10s} {'E off (J)':>10s}  " + \
            "  ".join(f"{c[:14]:>14s}" for c in self.clutches)
        lines = [head, f"{'':22s} {'':>5s} {'':>10s} {'':>10s}  " + "  ".join(f"{'N (ON)':>14s}" for _ in self.clutches)]
        for m in self.motions:
            for a, b in zip(self.curve(m, "on"), self.curve(m, "off")):
                flag = " *" if a.resolved or b.resolved else ""
                cells = "  ".join(f"{round(v, 1) + 0.0:14.1f}" for v in a.tension_N)  # no "-0.0"
                lines.append(f"{m[:22]:22s} {a.t:5.2f} {a.energy_J:10.4g} {b.energy_J:10.4g}  {cells}{flag}")
        if self.resolved():
            lines.append("* a frame re-solved (from the next frame's equilibrium, the evaluator's starts, or the "
                         "target's equilibrium): the first solve had ended in another, higher-energy equilibrium")
        if self.holding_N:
            slips = self.slips()
            lines += [f"{s['clutch']} slips in {s['motion']} from t = {s['from_t']:.2f} (holds {s['holding_N']:.0f} N)"
                      for s in slips] or ["no clutch reaches its holding force"]
        return "\n".join(lines)


def work_from_rest(points: list[tuple[float, float]]) -> float:
    """The work over a motion from its (t, garment energy J) frames sorted by t: the energy
    at the end less at the rest frame (t = 0); the energy at the end where there is no rest
    frame (a report made before paths had one); 0 without frames."""
    if not points:
        return 0.0
    rest = points[0][1] if points[0][0] == 0.0 else 0.0
    return points[-1][1] - rest


def _moving(curve: list[PathFrame], k: int) -> np.ndarray:
    """Clutch ``k``'s tension (N) in the frames of ``curve`` after rest."""
    return np.array([f.tension_N[k] for f in curve if f.t > 0.0] or [0.0])


def _rest_states(case, motions, sim_motions, kinds=STATES) -> tuple[dict, dict]:
    """The rest pose's states of ``motions``: ({(motion, state): its key}, {key: (evaluator
    key, SimState)}); states of equal activation (the key: its bytes) are one state."""
    key_of: dict[tuple[str, str], bytes] = {}
    unique: dict[bytes, tuple] = {}
    for m in motions:
        for s in kinds:
            a = np.asarray(case.on_activation(m) if s == "on" else np.zeros(case.n_clutches), dtype=np.float64)
            key_of[(m, s)] = b = a.tobytes()
            if b not in unique:  # keyed "@rest": the evaluator keeps equilibria per key (a motion may be "rest")
                label = f"on:{m}" if s == "on" else "off"  # "off": the clutched states' second start
                unique[b] = (("@rest", label), SimState.create(sim_motions[REST], a, name=f"rest[{label}]"))
    return key_of, unique


def _rest_starts(evaluator, design: np.ndarray, rest: tuple[dict, dict]) -> dict:
    """{(motion, state): the design's equilibrium at rest from the evaluator's starts} of the
    states ``rest`` (:func:`_rest_states`; :meth:`kgarment.design.Evaluator.equilibria`, kept
    by the evaluator: asking again is free)."""
    key_of, unique = rest
    best = dict(zip(unique, evaluator.equilibria(design, list(unique.values()))))
    return {k: best[b] for k, b in key_of.items()}


def rest_frames(evaluator, design: np.ndarray, problem, motions=None, frames: int = PATH_FRAMES,
                sim_motions=None, first: dict | None = None, attached=None, kinds=STATES) -> list[PathFrame]:
    """The rest pose (t = 0) of each motion of ``motions`` (default: the evaluator's), ON
    (its activation set) and OFF, as PathFrames: the lowest-energy converged equilibrium of
    the design there from the evaluator's starts (:meth:`kgarment.design.Evaluator.equilibria`:
    the skin-tight garment, the fully reinforced one's equilibrium, a clutched state also the
    garment as worn OFF) and, backwards, from each motion's first frame (t = 1 / ``frames``;
    the garment at rest has several equilibria: on the two-motion sleeve at subdivision 1
    the design OFF settled 4.4% lower coming back from flexion's first frame).  States of
    equal activation are one state.  ``sim_motions``, ``first``: the frames' motions
    (:func:`frame_motions` with ``rest``) and the first frames' equilibria {(motion,
    state): (N, 3)} where the caller has them; else they are made (the first frame solved
    from the rest equilibrium, as :func:`path_forces` starts); ``attached`` as there."""
    case, model = evaluator.case, evaluator.case.model
    motions = evaluator.motion_names(motions)
    design = np.asarray(design, dtype=np.float64)
    if sim_motions is None or first is None:
        sim_motions, index = frame_motions(problem, motions, frames, rest=True, attached=attached)
        labels = {m: next(label for label, mm, _ in index if mm == m) for m in motions}
    key_of, unique = rest = _rest_states(case, motions, sim_motions, kinds)
    start = _rest_starts(evaluator, design, rest)
    if first is None:
        keys = list(key_of)
        states = [SimState.create(sim_motions[labels[m]], unique[key_of[(m, s)]][1].activation, name=f"{m}@1[{s}]")
                  for m, s in keys]
        got = case.solve(design, states, options=case.solver,
                          warm_start=[predicted(model, _from_rest(start[k], sim_motions), st.motion)
                                      for k, st in zip(keys, states)])
        first = {k: r.x for k, r in zip(keys, got)}
    best = {key_of[k]: r for k, r in start.items()}
    keys = [k for k in key_of if k in first]
    back = case.solve(design, [dataclasses.replace(unique[key_of[k]][1], name=f"rest<-{k[0]}[{k[1]}]")
                                for k in keys], warm_start=[first[k] for k in keys], options=case.solver)
    for k, r in zip(keys, back):
        b = best[key_of[k]]
        if r.converged and (not b.converged or r.total_energy < b.total_energy * (1 - 1e-9)):
            best[key_of[k]] = r
    out = []
    for (m, s), b in key_of.items():
        r, st = best[b], unique[b][1]
        tension = clutch_tensions(model, design, st, r.x, case.solver)
        out.append(PathFrame(m, s, 0.0, float(r.total_energy), tuple(float(v) for v in tension), bool(r.converged)))
    return out


def _from_rest(r, sim_motions) -> list:
    """The rest equilibrium ``r`` (a StateResult) as the first of the equilibria a frame is
    predicted from (:func:`predicted`); none where it did not converge (the frame then
    starts from the skin-tight garment)."""
    return [(r.x, sim_motions[REST])] if r.converged else []


def path_forces(evaluator, design: np.ndarray, problem, motions=None, frames: int = PATH_FRAMES,
                report: Callable[[str], None] | None = None, attached=None, *, kinds=STATES,
                framed: tuple | None = None) -> PathReport:
    """The :class:`PathReport` of ``design`` (m,) over ``frames`` frames of each motion of
    ``motions`` (default: the evaluator's), ON and OFF.

    evaluator : kgarment.design.Evaluator of ``problem`` (its model and solver options);
    report : called with a line of progress before each frame (it may raise
    kgarment.errors.Cancelled to stop);  attached : (m,) bool, the garment's attached faces
    where the evaluator's garment has others than the problem's (the studio's painting);
    kinds : which of ON and OFF (the design loop's check: ON only);  framed : the frames
    (:func:`frame_motions` of ``frames`` with ``rest``) where the caller has them.
    """
    case = evaluator.case
    model = case.model
    if case.wearers:
        raise KgarmentError("--path: the force over the motion is solved on one body; a multi-body design's "
                            "wearers are evaluated at their target poses only (evaluate without --path)")
    motions = evaluator.motion_names(motions)
    sim_motions, index = framed or frame_motions(problem, motions, frames, rest=True, attached=attached)
    first = next(iter(sim_motions.values()))
    if first.garment_x0.shape != (model.n_garment, 3):
        raise KgarmentError("the frames' garment differs from the run's (another body or garment?)")
    design = np.asarray(design, dtype=np.float64)
    names = [c.name for c in model.clutches]

    def state(label: str, motion: str, s: str, anchor: np.ndarray | None = None) -> SimState:
        g = case.on_activation(motion) if s == "on" else np.zeros(case.n_clutches)
        return SimState.create(sim_motions[label], g, name=f"{label}[{s}]", anchor=anchor)

    by_motion = {m: [(label, t) for label, mm, t in index if mm == m] for m in motions}
    if report is not None:
        report("rest pose (t = 0)")
    rest_states = _rest_states(case, motions, sim_motions, kinds)
    rest = _rest_starts(evaluator, design, rest_states)
    # (motion, state, frame): (SimState, equilibrium) of the frames solved, the rest pose as frame -1
    solved_states = {(*k, -1): (rest_states[1][b][1], rest[k].x) for k, b in rest_states[0].items()
                     if rest[k].converged}
    results: dict[tuple[str, str, int], object] = {}

    def before(m: str, s: str, i: int) -> list:  # the (up to two) equilibria frame i is predicted from
        past = _from_rest(rest[(m, s)], sim_motions) + [(results[(m, s, j)].x, sim_motions[by_motion[m][j][0]])
                                                         for j in range(max(i - 2, 0), i)]
        return past[-2:]

    def held(m: str, s: str, i: int) -> np.ndarray | None:  # where friction holds frame i (module doc)
        return held_at(model, design, solved_states.get((m, s, i - 1)), sim_motions[by_motion[m][i][0]],
                       case.solver)

    started = time.perf_counter()
    for i in range(frames):
        if report is not None:
            spent = time.perf_counter() - started
            eta = f", {time_left(spent, i, frames)}" if i else ""
            report(f"frame {i + 1}/{frames} (t = {(i + 1) / frames:.2f}{eta})")
        keys = [(m, s, i) for m in motions for s in kinds]
        states = [state(by_motion[m][i][0], m, s, anchor=held(m, s, i)) for m, s, _ in keys]
        warm = [predicted(model, before(m, s, i), st.motion) for (m, s, _), st in zip(keys, states)]
        solved = case.solve(design, states, warm_start=warm, options=case.solver)
        retry = [j for j, r in enumerate(solved) if not r.converged]
        if retry:  # the evaluator's two starts (skin-tight, fully reinforced garment)
            # keyed by frame: the evaluator keeps equilibria per key, and a frame is not the target
            again = evaluator.equilibria(design, [((by_motion[keys[j][0]][i][0], keys[j][1]), states[j])
                                                  for j in retry])
            for j, r in zip(retry, again):
                solved[j] = r
        results.update(zip(keys, solved))
        solved_states.update({k: (st, r.x) for k, st, r in zip(keys, states, solved)})
    resolved: set = set()
    if model.friction == 0.0:  # with skin friction the state depends on the history: the frames stand
        resolved = _anchor_target(evaluator, design, motions, frames, by_motion, state=state, results=results)
        resolved |= _resolve_jumps(evaluator, design, motions, frames, by_motion, state=state, results=results)
    out = rest_frames(evaluator, design, problem, motions, sim_motions=sim_motions,
                      first={(m, s): results[(m, s, 0)].x for m in motions for s in kinds}, kinds=kinds)
    for m in motions:
        for s in kinds:
            for i, (label, t) in enumerate(by_motion[m]):
                r = results[(m, s, i)]
                tension = clutch_tensions(model, design, state(label, m, s), r.x, case.solver)
                out.append(PathFrame(m, s, t, float(r.total_energy), tuple(float(v) for v in tension),
                                     bool(r.converged), resolved=(m, s, i) in resolved))
    holding_n = tuple((m, tuple(float(h) for h in model.holding(case.on_activation(m)))) for m in motions) \
        if model.slips else ()
    ends = {(m, s): results[(m, s, frames - 1)] for m in motions for s in kinds}
    return PathReport(tuple(names), tuple(out), holding_n, ends)


def predicted(model, before: list, after) -> np.ndarray | None:
    """The warm start of a frame (the sim Motion ``after``) from the equilibria of the frames
    before it, ``before`` [(x (N, 3), sim Motion)], oldest first: none -> None (the
    skin-tight garment); one -> it carried with the body (:func:`carried`); two -> the secant
    predictor of path following: the later one carried, plus how the garment moved against
    the body over the step between them (carried to ``after`` too)."""
    if not before:
        return None
    x1, m1 = before[-1]
    c1 = carried(model, x1, m1, after)
    if len(before) == 1:
        return c1
    x0, m0 = before[-2]
    return c1 + (c1 - carried(model, x0, m0, after))


def carried(model, x: np.ndarray, before, after) -> np.ndarray:
    """An equilibrium x (N, 3) of the frame ``before`` (a sim Motion) carried to the frame
    ``after``: moved as the skin-tight garment (and its clutches) moves from one to the
    other, the warm start of the next frame's solve."""
    return x + model.initial_positions(after.garment_x0) - model.initial_positions(before.garment_x0)


def held_at(model, design: np.ndarray, before: tuple | None, motion, options) -> np.ndarray | None:
    """Where skin friction holds a frame (the sim Motion ``motion``) of a motion solved from
    rest: after the frame before, ``before`` = (its SimState, its equilibrium x (N, 3)),
    each vertex that slid is held the skin's give behind where it stands and each that stuck
    keeps its offset (:func:`kgarment.sim.held_after`), carried with the skin to ``motion``;
    None (the skin-tight garment) without friction or without a frame before (module doc)."""
    if before is None or model.friction == 0.0:
        return None
    st, x = before
    return carried(model, held_after(model, design, st, x, options), st.motion, motion)


def _anchor_target(evaluator, design, motions, frames, by_motion, state, results) -> set:
    """The last frame is the target pose: where the evaluator's equilibrium there (its two
    starts, :meth:`kgarment.design.Evaluator.solve_design`) has less energy than the path's,
    it replaces the last frame and the frames before are re-solved backwards, each from the
    next one's equilibrium, as long as that lowers their energy.  The backward sweeps of all
    (motion, state) paths go step by step together, one batch of solves per step (the
    workers share them; each path's sweep is what it would be alone).  Returns the keys
    replaced."""
    case = evaluator.case
    keys = [(m, s) for m in motions for s in STATES if (m, s, frames - 1) in results]
    # keyed like the evaluator's own target states: the same pose, so its equilibria there
    # (and its fully reinforced references) are reused and its numbers are the path's end
    targets = [((m, s), state(by_motion[m][-1][0], m, s)) for m, s in keys]
    replaced, sweep = set(), {}  # sweep: (motion, state) -> the frame to re-solve next
    last = frames - 1
    for (m, s), r in zip(keys, evaluator.equilibria(design, targets)):
        if not (r.converged and r.total_energy < results[(m, s, last)].total_energy * (1 - MULTISTABLE)):
            continue
        results[(m, s, last)] = r
        replaced.add((m, s, last))
        if last > 0:
            sweep[(m, s)] = last - 1
        log.info("%s[%s]: the path's end was above the target's equilibrium (%.4g J); re-solved backwards", m, s,
                 r.total_energy)
    while sweep:
        items = list(sweep.items())
        again = case.solve(design, [state(by_motion[m][i][0], m, s) for (m, s), i in items],
                            warm_start=[results[(m, s, i + 1)].x for (m, s), i in items], options=case.solver)
        sweep = {}
        for ((m, s), i), a in zip(items, again):
            if a.converged and a.total_energy < results[(m, s, i)].total_energy * (1 - 1e-9):
                results[(m, s, i)] = a
                replaced.add((m, s, i))
                if i > 0:
                    sweep[(m, s)] = i - 1
    return replaced


def _resolve_jumps(evaluator, design, motions, frames, by_motion, state, results) -> set:
    """Where the energy drops by more than PATH_JUMP from frame i - 1 to frame i, re-solve
    frame i - 1 from frame i's equilibrium and from the evaluator's two starts, and keep the
    lowest-energy converged equilibrium.  Every (motion, state) path is repaired on its own
    (:func:`_jump_repairs`); their solves go in one batch per step.  Returns the (motion,
    state, frame) keys replaced."""
    options = evaluator.case.solver
    replaced: set = set()
    pending = {}
    for m in motions:
        for s in (s for s in STATES if (m, s, 0) in results):
            gen = _jump_repairs(m, s, frames, by_motion, state, results, replaced=replaced)
            ask = next(gen, None)
            if ask is not None:
                pending[(m, s)] = (gen, ask)
    while pending:
        keys = list(pending)
        asks = [pending[k][1] for k in keys]  # (state, warm start, evaluator key)
        warm = evaluator.case.solve(design, [a[0] for a in asks], warm_start=[a[1] for a in asks], options=options)
        starts = evaluator.equilibria(design, [(a[2], a[0]) for a in asks])
        for k, w, e in zip(keys, warm, starts):
            gen = pending.pop(k)[0]
            try:
                pending[k] = (gen, gen.send([w, e]))
            except StopIteration:
                pass
    return replaced


def _jump_repairs(m, s, frames, by_motion, state, results, replaced):
    """The repairs of one (motion, state) path, as a generator: yields (SimState, warm start
    (N, 3), evaluator key) for each frame to re-solve and receives the equilibria found from
    the warm start and the evaluator's starts; updates ``results`` and ``replaced``."""
    for _ in range(frames):  # a replaced frame can expose a drop before it
        drops = [i for i in range(1, frames) if results[(m, s, i)].total_energy
                 < (1.0 - PATH_JUMP) * results[(m, s, i - 1)].total_energy]
        fixed = False
        for i in reversed(drops):
            label = by_motion[m][i - 1][0]
            st = state(label, m, s)
            tries = yield st, results[(m, s, i)].x, (label, s)
            best = min((r for r in tries if r.converged), key=lambda r: r.total_energy, default=None)
            if best is not None and best.total_energy < results[(m, s, i - 1)].total_energy * (1 - 1e-9):
                results[(m, s, i - 1)] = best
                replaced.add((m, s, i - 1))
                fixed = True
                log.info("%s[%s]: frame %d re-solved (%.4g J)", m, s, i, best.total_energy)
        if not fixed:
            return
