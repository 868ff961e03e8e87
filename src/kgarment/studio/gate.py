"""Who may use the studio: its own page, holding the session's token, and nothing else.

Serving on loopback keeps other machines out, not other web pages: any page open in the
user's browser can connect a WebSocket to ``ws://127.0.0.1:PORT``.  So every request to the
studio's port, the page's and the WebSocket's, passes :class:`Gate` first:

- ``Host`` must name the address served (on loopback: ``127.0.0.1``, ``localhost`` or
  ``[::1]`` with the port), which stops DNS rebinding;
- an ``Origin``, when sent (browsers always send one with a WebSocket), must be the origin
  served, ``http://HOST:PORT``: another site's page is refused;
- the session token, random per start: ``kgarment studio`` prints the URL with it
  (``http://127.0.0.1:PORT/?token=...``, as Jupyter does).  Opening that URL sets a cookie
  (``HttpOnly; SameSite=Strict``, named after the port) and redirects to ``/``; viser's
  client builds its WebSocket URL from the page's location without the query, so the
  WebSocket carries the token in that cookie (or ``?token=`` on its own URL, for scripts).

Anything else gets ``403 Forbidden`` with a one-line reason, before viser sees it.

How it hooks into viser 1.1: ``viser.ViserServer`` serves page and WebSocket on one port by
one call, ``websockets.asyncio.server.serve(..., process_request=...)``, made in its server
thread while ``ViserServer.__init__`` waits for the port; viser offers no hook there.
:func:`guarded_server` puts the gate in front of viser's ``process_request`` by wrapping that
call for the moment the server is made (under a lock; only viser's call is touched), and
refuses to start when viser no longer makes it: the studio never serves without its gate.
"""

from __future__ import annotations

import contextlib
import hmac
import io
import ipaddress
import logging
import secrets
import threading
from http import HTTPStatus
from urllib.parse import parse_qsl, urlencode, urlsplit

from kgarment.errors import KgarmentError

log = logging.getLogger(__name__)
TOKEN_PARAM = "token"
LOOPBACK_NAMES = ("127.0.0.1", "localhost", "[::1]")
_making = threading.Lock()  # one guarded server made at a time (the wrap is process-wide while it lasts)


def served_on_loopback(host: str) -> bool:
    """Whether ``host`` (the address served on) names this machine only."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class Gate:
    """The checks above for the studio served on ``host``, with ``token`` (default: a new
    random one).  On a loopback address only loopback host names (and ``host`` itself) are
    accepted in ``Host``; on another (``--allow-remote``) any, the Origin and the token being
    checked as ever."""

    def __init__(self, host: str = "127.0.0.1", token: str | None = None):
        self.token = token or secrets.token_urlsafe(24)
        self.loopback = served_on_loopback(host)
        self.names = tuple(dict.fromkeys((*LOOPBACK_NAMES, f"[{host}]" if ":" in host else host)))

    def cookie_name(self, port: int) -> str:
        return f"kgarment-studio-{port}"  # cookies are not per port: one per studio served

    def url(self, host: str, port: int) -> str:
        """The URL to open (the one the page and its WebSocket are let in with)."""
        return f"http://{host}:{port}/?{TOKEN_PARAM}={self.token}"

    def _good(self, token: str | None) -> bool:
        return token is not None and hmac.compare_digest(token.encode(), self.token.encode())

    def _host_ok(self, host: str, port: int) -> bool:
        if not host:
            return False
        if not self.loopback:
            return True
        return host in {f"{name}:{port}" for name in self.names}

    def refusal(self, request, port: int, cookie_header: str = "") -> tuple[str, str | None]:
        """("", None) to let ``request`` (a websockets Request) through to viser,
        ("redirect", location) to set the cookie and go to ``location``, or ("refuse",
        one-line reason)."""
        headers = request.headers
        try:
            host, origin = headers.get("Host", ""), headers.get("Origin")
        except LookupError:  # a header given twice
            return "refuse", "kgarment studio: Host or Origin given more than once"
        if not self._host_ok(host, port):
            return "refuse", f"kgarment studio: host {host!r} is not the address it serves"
        websocket = "websocket" in (v.lower() for v in headers.get_all("Upgrade"))
        if origin is not None and origin != f"http://{host}":
            return "refuse", f"kgarment studio: a page from {origin} may not connect; only the studio's own page"
        url = urlsplit(request.path)
        query = parse_qsl(url.query, keep_blank_values=True)
        given = [v for k, v in query if k == TOKEN_PARAM]
        if given:
            if not self._good(given[-1]):
                return "refuse", "kgarment studio: wrong token; open the URL that kgarment studio printed"
            if websocket:
                return "", None
            rest = urlencode([(k, v) for k, v in query if k != TOKEN_PARAM])
            return "redirect", "/" + (f"?{rest}" if rest else "")  # the page is "/"; never off this origin
        if self._good(_cookie(cookie_header, self.cookie_name(port))):
            return "", None
        return "refuse", ("kgarment studio: no session token; open the URL that kgarment studio printed "
                          f"(http://{host}/?{TOKEN_PARAM}=...)")

    def before(self, inner):
        """A websockets ``process_request`` that runs the gate, then ``inner`` (viser's)."""
        def process_request(connection, request):
            port = int(connection.local_address[1])
            verdict, text = self.refusal(request, port, "; ".join(request.headers.get_all("Cookie")))
            if verdict == "refuse":
                log.warning("studio: refused %s (%s)", request.path.partition("?")[0], text)
                return connection.respond(HTTPStatus.FORBIDDEN, text + "\n")
            if verdict == "redirect":
                response = connection.respond(HTTPStatus.FOUND, "")
                response.headers["Location"] = text
                response.headers["Set-Cookie"] = (f"{self.cookie_name(port)}={self.token}; Path=/; HttpOnly; "
                                                  "SameSite=Strict")
                return response
            return None if inner is None else inner(connection, request)
        return process_request


def _cookie(header: str, name: str) -> str | None:
    """The value of cookie ``name`` in a ``Cookie`` header (None: not there)."""
    for part in header.split(";"):
        key, eq, value = part.strip().partition("=")
        if eq and key == name:
            return value
    return None


def guarded_server(gate: Gate, host: str, port: int, **kwargs):
    """A ``viser.ViserServer(host, port, **kwargs)`` whose every request passes ``gate``
    (see the module docstring for how); a one-line error when viser serves some other way."""
    import viser
    import websockets.asyncio.server as ws_server
    from viser.infra import _infra

    original = ws_server.serve
    hooked: list[str] = []

    def serve(handler, *args, process_request=None, **kw):
        if getattr(handler, "__module__", None) == _infra.__name__:  # viser's call, none other
            hooked.append(handler.__qualname__)
            process_request = gate.before(process_request)
        return original(handler, *args, process_request=process_request, **kw)

    banner = io.StringIO()  # viser prints its address without the token: not the one to open
    with _making, contextlib.redirect_stdout(banner):
        ws_server.serve = serve
        try:
            server = viser.ViserServer(host=host, port=port, **kwargs)
        finally:
            ws_server.serve = original
    log.debug("viser: %s", banner.getvalue())
    if not hooked:
        server.stop()
        raise KgarmentError(f"viser {viser.__version__} serves its page in a way the studio's gate does not know "
                            "(kgarment.studio.gate); the studio will not serve without it: install viser 1.1")
    return server
