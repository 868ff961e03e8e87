"""The studio's longer actions: simulations, optimisations, runs, files.

A mixin of :class:`kgarment.studio.app.Studio` (split off to keep files short). Jobs run
in background threads on frozen copies of the edited state, so a failing simulation or
optimisation leaves every edit in place and only shows its error.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from kgarment.errors import KgarmentError

log = logging.getLogger(__name__)


class Actions:
    """Simulate, compare, optimise, scrub runs, save and open (see the module docstring)."""

    # ----- simulation -------------------------------------------------------------------
    def simulate(self, which: str = "A", motions=None):
        """Simulate design A (the edited one) or B on ``motions`` in the background;
        returns the Job (or None when one is running already)."""
        from kgarment.studio.evaluate import evaluate
        from kgarment.studio.jobs import Job

        if self.sim_job is not None and self.sim_job.running:
            raise KgarmentError("a simulation is running; wait for it or press Stop simulation")
        if which == "B" and self.compare is None:
            raise KgarmentError("there is no design B yet (pin A as B, or load one)")
        motions = list(motions or self.settings.sim_motions)
        if not motions:
            raise KgarmentError("tick at least one motion to simulate")
        st = self.state
        with st.lock:
            problem, body, garment, strips = st.problem, st.body, st.garment, st.strips()
            design = st.design.copy() if which == "A" else self.compare[1].copy()
            revision = st.revision
        label = "A" if which == "A" else f"B ({self.compare[0]})"

        def work(job):
            return evaluate(problem, body, garment, strips, design, motions, label=label, revision=revision,
                            device=self.device, full_cache=self.full_cache, report=job.report,
                            cancelled=lambda: job.cancelled)

        def done(ev):
            if which == "A":
                self.eval_a = ev
            else:
                self.eval_b = ev
            self.say(f"simulated design {label} on {', '.join(motions)} in {time.time() - job.started:.0f} s", notify=True)
            self.panel.show_results()
            self.redraw(body=False)

        job = Job("simulation", work, on_done=done, on_error=lambda m: self.say(m, error=True),
                  on_report=self.panel.show_sim_status, on_cancel=lambda: self.say("simulation stopped", notify=True))
        self.say(f"simulating design {label} on {', '.join(motions)} ...")
        self.sim_job = job.start()
        return job

    def stop_simulation(self) -> None:
        if self.sim_job is None or not self.sim_job.running:
            raise KgarmentError("no simulation is running")
        self.sim_job.cancel()
        self.say("stopping the simulation after the current solve ...")

    def pin_as_b(self) -> None:
        """Design A (and its results, if current) becomes design B for comparisons."""
        st = self.state
        with st.lock:
            self.compare = (f"A at edit {st.revision}", st.design.copy())
            a = self.eval_a
            if a is not None and a.revision == st.revision:
                from dataclasses import replace

                self.eval_b = replace(a, label=f"B ({self.compare[0]})")
            else:
                self.eval_b = None
        self.say(f"design A pinned as B ({self.compare[0]})")
        self.panel.show_results()
        self.redraw(body=False)

    def load_b(self, source: str) -> None:
        """Design B from a design file (.npz/.npy/.txt) or RUN / RUN@K."""
        from kgarment.simulate import load_design

        text = source.strip()
        if not text:
            raise KgarmentError("give a design file, a run folder or RUN@ITERATION")
        run = Path(text.partition("@")[0])
        if run.is_dir():
            from kgarment.studio.runs import check_compatible, open_run

            check_compatible(open_run(run), self.state.problem, self.state.n_faces)
        d = load_design(text, self.state.n_faces) > 0.5
        self.compare, self.eval_b = (Path(text).name or text, d), None
        self.say(f"design B loaded from {text} ({100 * np.mean(d):.1f}% of faces reinforced)")
        self.panel.show_results()
        self.redraw(body=False)

    # ----- optimisation -----------------------------------------------------------------
    def optimise(self, folder: str | None = None, max_iterations: int | None = None):
        """Start BESO from the current problem, clutches and attachments into a run folder;
        the run is opened in the page and follows the iterations live. Returns the Job."""
        import dataclasses

        from kgarment.studio.jobs import Job
        from kgarment.studio.optimise import inputs_from_state, run_optimisation
        from kgarment.studio.runs import RunHistory

        if self.opt_job is not None and self.opt_job.running:
            raise KgarmentError("an optimisation is running; stop it first")
        run = Path(folder) if folder else self.runs_root / time.strftime("studio-%Y%m%d-%H%M%S")
        if run.exists() and any(run.iterdir()):
            raise KgarmentError(f"run folder {run} exists and is not empty; choose another")
        inp = inputs_from_state(self.state)
        if max_iterations:
            d = dataclasses.replace(inp.problem.design, max_iterations=int(max_iterations))
            inp = dataclasses.replace(inp, problem=dataclasses.replace(inp.problem, design=d))
        m = self.state.n_faces
        self.run = RunHistory(run, inp.problem, np.zeros((0, m), bool), [])
        self.run_k = 0

        def iteration(row, design):
            with self.lock:
                if self.run is not None and self.run.folder == run:
                    self.run.designs = np.concatenate([self.run.designs, design[None]])
                    self.run.metrics.append(row)
                    if self.panel.follow_latest():
                        self.run_k = self.run.n_iterations - 1
            self.panel.show_run()
            if self.settings.mode == "run":
                self.redraw(body=False)

        def work(job):
            return run_optimisation(inp, run, device=self.device, on_iteration=iteration,
                                    cancelled=lambda: job.cancelled, finish=True)

        def done(st):
            self.say(f"optimisation finished after {len(st.metrics)} iterations; run folder {run}", notify=True)

        job = Job("optimisation", work, on_done=done, on_error=lambda msg: self.say(msg, error=True),
                  on_report=self.panel.show_opt_status,
                  on_cancel=lambda: self.say(f"optimisation stopped; resume with: kgarment design --resume {run}", notify=True))
        self.settings.mode = "run"
        self.panel.sync_settings()
        self.panel.show_run()
        self.say(f"optimisation started into {run}")
        self.opt_job = job.start()
        return job

    def stop_optimisation(self) -> None:
        if self.opt_job is None or not self.opt_job.running:
            raise KgarmentError("no optimisation is running")
        self.opt_job.cancel()
        self.say("stopping the optimisation after the current iteration ...")

    # ----- runs -------------------------------------------------------------------------
    def open_run(self, folder) -> None:
        """Open a run folder for scrubbing (it must fit the studio's body and garment)."""
        from kgarment.studio.runs import check_compatible, open_run

        run = open_run(folder)
        check_compatible(run, self.state.problem, self.state.n_faces)
        with self.lock:
            self.run = run
            self.run_k = max(run.n_iterations - 1, 0)
            self.settings.mode = "run"
        self.panel.sync_settings()
        self.panel.show_run()
        self.say(f"run {run.folder} opened: {run.n_iterations} iterations")
        self.redraw(body=False)

    def show_iteration(self, k: int) -> None:
        if self.run is None:
            raise KgarmentError("no run is open")
        self.run.design(k)
        self.run_k = int(k)
        self.panel.show_run()
        if self.settings.mode == "run":
            self.redraw(body=False)

    def _run_design(self) -> np.ndarray:
        if self.run is None:
            raise KgarmentError("no run is open (Optimise tab: open a run folder or start an optimisation)")
        return self.run.design(self.run_k)

    def use_iteration(self, as_b: bool = False) -> None:
        """Copy the shown iteration into design A (undoable) or make it design B."""
        d = self._run_design()
        label = f"{self.run.folder.name}@{self.run_k}"
        if as_b:
            self.compare, self.eval_b = (label, d.copy()), None
            self.say(f"design B is now {label}")
            self.panel.show_results()
        else:
            self.state.set_layer("design", d)
            self.say(f"design A is now {label} (undo restores the previous one)")
        self.redraw(body=False)

    def export_iteration(self, path: str) -> Path:
        """Write the shown iteration as a design NPZ (``kgarment simulate --design`` reads it)."""
        from kgarment.studio.session import export_design

        if not path.strip():
            raise KgarmentError("give a file name for the design (.npz)")
        out = export_design(path.strip(), self._run_design(), self.state.base_garment, iteration=self.run_k)
        self.say(f"iteration {self.run_k} written to {out}", notify=True)
        return out

    def export_a(self, path: str) -> Path:
        from kgarment.studio.session import export_design

        if not path.strip():
            raise KgarmentError("give a file name for the design (.npz)")
        out = export_design(path.strip(), self.state.design, self.state.base_garment)
        self.say(f"design A written to {out}", notify=True)
        return out

    # ----- files ------------------------------------------------------------------------
    def save(self, folder: str | None = None) -> list[Path]:
        """Save the session (problem, clutches, designs, attachments, settings, results)."""
        from kgarment.studio.session import save_session

        target = Path(folder.strip()) if folder and folder.strip() else self.session_dir
        if target is None:
            raise KgarmentError("give a session folder to save into")
        results = {k: e.to_json() for k, e in (("A", self.eval_a), ("B", self.eval_b)) if e is not None}
        paths = save_session(self.state, target, settings=self.settings.to_dict(), compare=self.compare,
                             results=results, run=self.run.folder if self.run is not None else None)
        self.session_dir = target
        self.say(f"session saved to {target} ({len(paths)} files)", notify=True)
        self.panel.refresh_status()
        return paths

    def open(self, path: str, force: bool = False) -> None:
        """Replace the studio's contents by a problem file, run folder or session. With
        unsaved changes the first call only warns; a second call with the same path opens."""
        from kgarment.studio.session import build_state, read_source

        text = path.strip()
        if not text:
            raise KgarmentError("give a problem file, a run folder or a session folder to open")
        if any(j is not None and j.running for j in (self.sim_job, self.opt_job)):
            raise KgarmentError("a simulation or optimisation is running; stop it before opening something else")
        if self.state.dirty and not force and self._confirm_open != text:
            self._confirm_open = text
            raise KgarmentError("there are unsaved changes: save them, or press Open again to discard them")
        opened = read_source(text)
        body = self.state.body if opened.problem.body == self.state.problem.body else None
        new = build_state(opened, body)
        with self.lock:
            self.state, self._confirm_open = new, None
            self.session_dir = opened.session or self.session_dir
            self.compare = opened.compare
            self.eval_a = self.eval_b = None
            self.selected, self.pending_start, self.run = None, None, None
            self.full_cache = {}
            from kgarment.studio.app import Settings

            self.settings = Settings.from_dict(opened.settings)
            self._fix_settings()
        self.panel.rebuild_for_state()
        self._set_initial_camera()
        self.redraw()
        self.say(f"opened {text} ({opened.kind}): {new.base_garment.name}, {new.n_faces} faces, "
                 f"{len(new.clutches)} clutches", notify=True)
        if opened.run is not None:
            self.guarded(self.open_run, opened.run)
