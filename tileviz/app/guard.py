"""Which websocket connections the demo server serves (``SECURITY.md``).

A browser lets any web page open a websocket to ``127.0.0.1``: without a check, a page of
another site the user has open could drive the demo (start recordings, kidnap the robot). The
server therefore serves a connection only when it is not a page of another site:

- a connection without an ``Origin`` header is a program (the tests' client, a script), not a
  page: served;
- a page's ``Origin`` must be the server's own address as the browser reached it (the request's
  ``Host``): the page the server itself served;
- while the server listens on a loopback address only, the ``Host`` must be a loopback name
  (``localhost``, ``127.x.y.z``, ``[::1]``): a page of another site whose name was made to point
  at 127.0.0.1 (DNS rebinding) is refused too.

Any other connection is closed (code 1008) before anything is sent to it or read from it.
"""

from __future__ import annotations

import ipaddress
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any
from urllib.parse import urlsplit

if TYPE_CHECKING:
    from viser import ViserServer

__all__ = ["is_loopback", "origin_problem", "refuse_foreign_pages"]


def is_loopback(host: str) -> bool:
    """Whether ``host`` (an address to listen on or a name in a URL) is this machine only."""
    h = host.strip().strip("[]").lower()
    if h == "localhost" or h.endswith(".localhost"):
        return True
    try:
        return ipaddress.ip_address(h).is_loopback
    except ValueError:
        return False


def _hostname(netloc: str) -> str:
    return (urlsplit(f"//{netloc}").hostname or "").lower()


def origin_problem(origin: str | None, host: str | None, *, loopback_only: bool) -> str | None:
    """Why a websocket request with these ``Origin`` and ``Host`` headers is not served (module
    docstring), or None when it is. ``loopback_only``: the server listens on loopback only."""
    if loopback_only and host is not None and not is_loopback(_hostname(host)):
        return f"Host {host!r} is not this machine's loopback name"
    if origin is None:
        return None
    if origin == "null":
        return "a page without an origin (a file or a sandboxed frame)"
    parts = urlsplit(origin)
    if parts.scheme not in ("http", "https") or not parts.netloc:
        return f"Origin {origin!r} is not a web page's"
    if host is None or parts.netloc.lower() != host.strip().lower():
        return f"a page of {origin} is not this server's ({host})"
    return None


def _headers(connection: Any) -> Mapping[str, str] | None:
    request = getattr(connection, "request", None)
    headers = getattr(request, "headers", None)
    return headers if headers is not None and hasattr(headers, "get") else None


def refuse_foreign_pages(server: ViserServer, listen_host: str,
                         report: Callable[[str], None]) -> bool:
    """Have ``server`` close every websocket connection :func:`origin_problem` refuses, before
    it is served; ``report`` gets one line per refused origin (the first time). False when this
    viser version lacks what the check reads (then no connection is checked)."""
    ws = getattr(server, "_websock_server", None)
    live = getattr(ws, "_live_connections", None)
    connect = getattr(ws, "on_client_connect", None)
    if not isinstance(live, dict) or connect is None:
        return False
    loopback_only = is_loopback(listen_host)
    reported: set[str] = set()

    async def check(client: Any) -> None:
        connection = live.get(getattr(client, "client_id", None))
        if connection is None:
            return
        headers = _headers(connection)
        if headers is None:
            return
        origin, host = headers.get("Origin"), headers.get("Host")
        why = origin_problem(origin, host, loopback_only=loopback_only)
        if why is None:
            return
        await connection.close(1008, "not served: a page of another site")
        key = f"{origin} {host}"
        if key not in reported and len(reported) < 100:
            reported.add(key)
            report(f"refused a websocket connection: {why}")

    connect(check)
    return True
