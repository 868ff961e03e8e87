"""Progress as plain lines where standard output is not a terminal (kgarment.cli.progress)."""

from __future__ import annotations

from kgarment.cli.progress import LineProgress, clock_text


class Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_clock_text():
    assert clock_text(3725) == "1:02:05"
    assert clock_text(59.4) == "0:00:59"
    assert clock_text(None) == "-:--:--" and clock_text(float("nan")) == "-:--:--"


def test_lines_are_throttled_and_the_last_state_is_printed_once():
    clock, lines = Clock(), []
    with LineProgress(lambda t: f"it {t['completed']} of ~{t['total']}", every=30.0, clock=clock,
                      write=lines.append) as bar:
        task = bar.add_task("starting", total=10)
        for now, done in ((12, 1), (20, 2), (45, 3), (50, 4)):
            clock.now = now
            bar.update(task, completed=done, description=f"step {done}")
        clock.now = 90.0  # the work after the last step (a final evaluation) is not a step's
    # the first update; 33 s later the next; the last state at the end.  ETA: the steps left
    # at the mean time per step so far (9 x 12 s, 7 x 45/3 s, 6 x 50/4 s)
    assert lines == ["it 1 of ~10  step 1  0:00:12 elapsed, ETA 0:01:48",
                     "it 3 of ~10  step 3  0:00:45 elapsed, ETA 0:01:45",
                     "it 4 of ~10  step 4  0:00:50 elapsed, ETA 0:01:15"]


def test_resumed_steps_do_not_count_for_the_rate_and_totals_may_grow():
    clock, lines = Clock(), []
    with LineProgress(lambda t: f"{t['run']}: {t['completed']}/{t['total']}", every=0.0, clock=clock,
                      write=lines.append) as bar:
        task = bar.add_task("", total=20, completed=10, run="r")  # 10 done before this process
        clock.now = 8.0
        bar.update(task, completed=12, total=24)
    # 2 steps in 8 s, 12 left; printed at the update, nothing more at the end
    assert lines == ["r: 12/24  0:00:08 elapsed, ETA 0:00:48"]


def test_a_task_without_a_total_has_no_eta():
    clock, lines = Clock(), []
    with LineProgress(lambda t: "tasks", clock=clock, write=lines.append) as bar:
        task = bar.add_task("running a")
        clock.now = 5.0
        bar.update(task, completed=1)
    assert lines == ["tasks  running a  0:00:05 elapsed"]


def test_a_sweep_s_progress_comes_as_lines_off_a_terminal(capsys):
    """``kgarment sweep`` under nohup or CI: its first state and its last, as lines."""
    from kgarment.cli.sweep import sweep_progress
    from kgarment.sweep.execute import SweepProgress

    with sweep_progress(2, {"a": 10, "b": 10}, quiet=False) as update:
        update(SweepProgress(2, running={"a": 0, "b": 0}))
        update(SweepProgress(2, running={"a": 4, "b": 3}))
        update(SweepProgress(2, finished=1, failed=1))
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("0/2 tasks  running a it 0, b it 0  0:00:00 elapsed, ETA ")
    assert lines[-1].startswith("2/2 tasks  1 failed  0:00:0") and len(lines) == 2
