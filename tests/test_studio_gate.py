"""Who may use the studio and what its page may read (issue 80): only its own page, holding
the session token, connects (another Origin, no token or a wrong one: 403 before viser sees
the request); every path typed into the page is refused, unread, outside the studio's
folders; an out-of-range budget keeps the last valid one; the File tab exports the design
the view shows."""

from __future__ import annotations

import http.cookiejar
import sys
import types
import urllib.error
import urllib.request

import numpy as np
import pytest

pytest.importorskip("viser")

from test_studio import fake_run
from test_studio_app import free_port, last, problem

from kgarment.errors import KgarmentError
from kgarment.studio.session import Opened


@pytest.fixture()
def studio(anny_body, tmp_path):
    """A studio on the default problem, --runs and --session under tmp_path (as test_studio_app's)."""
    from kgarment.studio.app import Studio

    s = Studio(Opened("default", problem()), port=free_port(), session=tmp_path / "session",
               runs=tmp_path / "runs", body=anny_body)
    yield s
    s.stop()

# ----- what the process opens (audit hooks cannot be removed: this one records only when asked)
_opened: list[str] | None = None


def _audit(event, args):
    if _opened is not None and event in ("open", "os.listdir", "os.scandir") and args and args[0] is not None:
        _opened.append(str(args[0]))


sys.addaudithook(_audit)


def opened_during(fn, *args):
    """(the exception fn(*args) raised or None, the paths the process opened or listed)."""
    global _opened
    _opened = []
    try:
        fn(*args)
        exc = None
    except Exception as e:  # noqa: BLE001  (returned to the test)
        exc = e
    finally:
        seen, _opened = _opened, None
    return exc, seen


def ws_connect(url, origin=None, cookie=None):
    """Open a WebSocket as viser's client does (its subprotocol); returns the first message's
    size, or the HTTP status the handshake was refused with."""
    import viser
    from websockets.exceptions import InvalidStatus
    from websockets.sync.client import connect

    headers = {"Cookie": cookie} if cookie else None
    try:
        with connect(url, origin=origin, additional_headers=headers, open_timeout=10,
                     subprotocols=[f"viser-v{viser.__version__}"]) as c:
            return len(c.recv(timeout=10))
    except InvalidStatus as exc:
        return exc.response.status_code


# ----- the gate on a live studio -------------------------------------------------------------
def test_only_the_studios_own_page_with_its_token_connects(studio):
    port = studio.server.get_port()
    ws, own = f"ws://127.0.0.1:{port}", f"http://127.0.0.1:{port}"
    assert ws_connect(ws, origin="http://evil.example.com") == 403  # the script: it got in
    assert ws_connect(ws, origin=own) == 403  # no token
    token = studio.gate.token
    assert studio.url == f"http://127.0.0.1:{port}/?token={token}" and len(token) >= 24
    cookie = f"{studio.gate.cookie_name(port)}={token}"
    assert ws_connect(f"{ws}/?token={token}", origin="http://evil.example.com") == 403  # even with the token
    assert ws_connect(ws, origin="http://evil.example.com", cookie=cookie) == 403
    assert ws_connect(f"{ws}/?token={token}", origin="null") == 403
    assert ws_connect(f"{ws}/?token=wrong{token}", origin=own) == 403
    assert ws_connect(ws, origin=own, cookie=f"{studio.gate.cookie_name(port)}=nope") == 403
    assert ws_connect(f"{ws}/?token={token}", origin=f"http://evil.example.com:{port}") == 403
    assert studio.server.get_clients() == {}  # none of them ever reached viser
    assert ws_connect(f"{ws}/?token={token}", origin=own) > 0  # the page's scene and controls
    assert ws_connect(ws, origin=own, cookie=cookie) > 0  # the token in the cookie, as the page has it


def test_the_page_needs_the_token_and_dns_rebinding_is_refused(studio):
    port = studio.server.get_port()
    for url, headers in ((f"http://127.0.0.1:{port}/", {}),
                         (f"http://127.0.0.1:{port}/?token=nope", {}),
                         (studio.url, {"Host": f"evil.example.com:{port}"})):  # a rebound name: not served
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(urllib.request.Request(url, headers=headers), timeout=10)
        assert err.value.code == 403
        assert len(err.value.read().decode().strip().splitlines()) == 1
    jar = http.cookiejar.CookieJar()
    browser = urllib.request.build_opener(urllib.request.HTTPCookieProcessor(jar))
    page = browser.open(studio.url, timeout=10)  # sets the cookie and goes to / without the token
    assert page.status == 200 and page.url == f"http://127.0.0.1:{port}/" and "<html" in page.read().decode().lower()
    (c,) = list(jar)
    assert c.name == studio.gate.cookie_name(port) and c.value == studio.gate.token
    assert c.has_nonstandard_attr("HttpOnly") and c.get_nonstandard_attr("SameSite") == "Strict"
    assert browser.open(f"http://127.0.0.1:{port}/", timeout=10).status == 200  # the cookie lets it in again


def test_the_gate_never_redirects_off_its_origin():
    from kgarment.studio.gate import Gate

    g = Gate("127.0.0.1", token="t" * 32)
    req = types.SimpleNamespace(path=f"//evil.example.com/x?token={g.token}&a=1", headers=_Headers(Host="127.0.0.1:9"))
    assert g.refusal(req, 9) == ("redirect", "/?a=1")
    req.path = f"/\\evil.example.com?token={g.token}"  # browsers take a backslash for a slash: still "/"
    assert g.refusal(req, 9) == ("redirect", "/")
    remote = Gate("0.0.0.0", token="t" * 32)  # --allow-remote: any Host, its own Origin only
    ok = types.SimpleNamespace(path=f"/?token={g.token}", headers=_Headers(Host="10.0.0.5:9", Origin="http://10.0.0.5:9",
                                                                          Upgrade="websocket"))
    assert remote.refusal(ok, 9) == ("", None) and g.refusal(ok, 9)[0] == "refuse"


class _Headers(dict):
    def get_all(self, key):
        return [self[key]] if key in self else []


def test_the_studio_refuses_to_serve_when_viser_serves_another_way(monkeypatch):
    """The gate wraps viser 1.1's one call that serves page and WebSocket; a viser that no
    longer makes it gets a one-line refusal, never an unguarded server."""
    import viser

    from kgarment.studio.gate import Gate, guarded_server

    stopped = []

    class Elsewhere:  # a server that comes up without websockets.asyncio.server.serve
        def __init__(self, **kw):
            pass

        def stop(self):
            stopped.append(True)

    monkeypatch.setattr(viser, "ViserServer", Elsewhere)
    with pytest.raises(KgarmentError, match="the studio will not serve without it") as err:
        guarded_server(Gate(), host="127.0.0.1", port=free_port(), verbose=False)
    assert stopped == [True] and "\n" not in str(err.value)


# ----- what the page may read ------------------------------------------------------------------
def test_paths_outside_the_studios_folders_are_refused_unread(studio, tmp_path):
    n = studio.state.n_faces
    outside = tmp_path / "outside"
    outside.mkdir()
    np.savetxt(outside / "b.txt", np.ones(n))  # a valid design: today's studio loaded it
    fake_run(outside / "run", problem(), np.ones((2, n), bool))
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / "link.txt").symlink_to(outside / "b.txt")  # inside by name, outside in fact
    for fn, text in ((studio.sims.load_b, "/etc/passwd"), (studio.sims.load_b, str(outside / "b.txt")),
                     (studio.sims.load_b, str(tmp_path / "runs" / "link.txt")),
                     (studio.sims.load_b, f"{outside / 'run'}@1"), (studio.sims.load_b, str(tmp_path / "runs" / "..")),
                     (studio.optimiser.open, str(outside / "run")), (studio.open, "/etc/passwd"),
                     (studio.open, str(outside / "run"))):
        exc, seen = opened_during(fn, text)
        assert isinstance(exc, KgarmentError) and "reads only under its folders" in str(exc), (text, exc)
        assert "\n" not in str(exc) and "root:" not in str(exc)
        assert not [p for p in seen if p.startswith(("/etc/passwd", str(outside)))], (text, seen)
    assert studio.sims.design_b is None and studio.optimiser.run is None
    studio.guarded(studio.sims.load_b, "/etc/passwd")  # in the page: one line, not the file's first line
    assert last(studio)[1] and "reads only under" in last(studio)[0] and "root:" not in studio.panel.message.content
    inside = tmp_path / "runs" / "b.txt"
    np.savetxt(inside, np.ones(n))
    studio.sims.load_b(str(inside))  # under --runs: read
    assert studio.sims.design_b.design.all()


def test_the_studios_folders_are_those_of_its_command_line(tmp_path):
    from kgarment.studio.folders import Folders
    from kgarment.studio.session import read_source

    (tmp_path / "proj").mkdir()
    (tmp_path / "proj" / "p.toml").write_text('[garment]\ntemplate = "arm_sleeve.right"\n')
    f = Folders.of(read_source(tmp_path / "proj" / "p.toml"), tmp_path / "runs", tmp_path / "s")
    assert f.roots == ((tmp_path / "runs").resolve(), (tmp_path / "proj").resolve(), (tmp_path / "s").resolve())
    assert f.inside(f"{tmp_path / 'proj' / 'run'}@3", "design B").name == "run@3"
    with pytest.raises(KgarmentError, match="reads only under"):
        f.inside(f"{tmp_path / 'proj'}/../x", "design B")
    assert Folders.of(read_source(None), tmp_path / "runs").roots == ((tmp_path / "runs").resolve(),)


# ----- the budget and the export ---------------------------------------------------------------
def test_an_out_of_range_budget_keeps_the_last_valid_one(studio):
    """Typing 5: refused, and the number box's clamp to 1 that follows is not taken for the
    user's (it made the budget 100% and the next optimisation ran with target_area = 1)."""
    from kgarment.studio.optimise import RunInputs

    panel, st = studio.panel, studio.state
    assert st.budget == pytest.approx(0.15)
    studio.guarded(panel._set_budget, 5.0)
    assert last(studio) == ("budget 5.0 is outside [0.01, 1]", True)
    assert panel.budget.value == pytest.approx(0.15) and st.budget == pytest.approx(0.15)
    studio.guarded(panel._set_budget, 1.0)  # the box's clamp of the refused 5
    assert st.budget == pytest.approx(0.15) and panel.budget.value == pytest.approx(0.15)
    assert RunInputs.of(st).problem.design.beso.target_area == pytest.approx(0.15)
    studio.guarded(panel._set_budget, -1.0)
    studio.guarded(panel._set_budget, 0.01)  # its clamp at the low end
    assert st.budget == pytest.approx(0.15)
    panel._set_budget(0.3)
    panel._set_budget(1.0)  # chosen, not a clamp: taken
    assert st.budget == pytest.approx(1.0) and "100%" in panel.coverage.content


def test_the_file_tab_exports_the_design_shown(studio, tmp_path):
    from kgarment.design import load_design

    n = studio.state.n_faces
    designs = np.zeros((2, n), bool)
    designs[0], designs[1, ::4] = True, True
    run = fake_run(tmp_path / "runs" / "r", problem(), designs)
    studio.optimiser.open(str(run))
    assert studio.settings.mode == "run" and studio.optimiser.k == 1 and not studio.state.design.any()
    out = studio.export_shown("shown")
    assert np.array_equal(load_design(out, n) > 0.5, designs[1])  # what the view shows, not the empty A
    assert "iteration 1 of run r" in last(studio)[0] and "not design A" in last(studio)[0]
    studio.settings.mode = "design"
    out = studio.export_shown("a")
    assert not (load_design(out, n) > 0.5).any() and last(studio)[0].startswith("design A written to")
