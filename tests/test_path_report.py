"""The force-over-the-motion report's arithmetic: work from rest, means after rest, and a
cached report (made before paths had a rest frame) brought up to date."""

from __future__ import annotations

import pytest

from kgarment.evaluate.path import PathFrame, PathReport
from kgarment.reproduce.figures import force_curves, force_stats


def _frames(rest: bool) -> tuple[PathFrame, ...]:
    """Two clutches, one motion: ON energy 10 J at rest rising to 13 J, OFF 9 J to 9.5 J."""
    on = [(0.0, 10.0, (40.0, 1.0)), (0.5, 11.0, (100.0, 2.0)), (1.0, 13.0, (160.0, 3.0))]
    off = [(0.0, 9.0, (0.5, 0.0)), (0.5, 9.2, (0.7, 0.0)), (1.0, 9.5, (0.9, 0.0))]
    out = [PathFrame("m", s, t, e, f, True) for s, rows in (("on", on), ("off", off)) for t, e, f in rows]
    return tuple(f for f in out if rest or f.t > 0.0)


def test_the_work_over_the_motion_is_counted_from_rest():
    rep = PathReport(("a", "b"), _frames(rest=True))
    a, b = rep.summary()
    assert a["work_on_J"] == pytest.approx(13.0 - 10.0) and a["work_off_J"] == pytest.approx(9.5 - 9.0)
    assert a["energy_on_J"] == 13.0 and a["energy_off_J"] == 9.5
    assert a["peak_on_N"] == 160.0 and a["mean_on_N"] == pytest.approx((100.0 + 160.0) / 2)  # mean: after rest
    assert b["peak_on_N"] == 3.0 and b["mean_off_N"] == 0.0
    # the reproduction's figures read the same numbers from the JSON
    doc = rep.to_json()
    st = force_stats(doc, "m")
    assert st["on"]["work"] == pytest.approx(3.0) and st["off"]["work"] == pytest.approx(0.5)
    assert st["on"]["peak"] == 160.0 and st["on"]["mean"] == pytest.approx(130.0)
    assert force_curves(doc, "m", "on") == ([0.0, 0.5, 1.0], [40.0, 100.0, 160.0])


def test_a_report_without_its_rest_frame_gets_it_added():
    old = PathReport(("a", "b"), _frames(rest=False))
    doc = old.to_json()
    # before: nothing known at rest, the curve drawn from (0, 0), the work the energy at the target
    assert force_curves(doc, "m", "on") == ([0.0, 0.5, 1.0], [0.0, 100.0, 160.0])
    assert force_stats(doc, "m")["on"]["work"] == 13.0
    back = PathReport.from_json(doc)
    assert back.frames == old.frames and not back.has_rest
    rest = [f for f in _frames(rest=True) if f.t == 0.0]
    new = back.with_rest(rest)
    assert new.has_rest and new.summary() == PathReport(("a", "b"), _frames(rest=True)).summary()
    assert PathReport.from_json(new.to_json()).summary() == new.summary()
    assert new.to_json()["rest_starts"] >= 2 and "rest_starts" not in doc
    # a rest frame solved again replaces the one before, it is not added twice
    again = new.with_rest([PathFrame(f.motion, f.state, 0.0, f.energy_J - 1.0, f.tension_N, True) for f in rest])
    assert len(again.frames) == len(new.frames)
    assert again.summary()[0]["work_on_J"] == pytest.approx(new.summary()[0]["work_on_J"] + 1.0)
