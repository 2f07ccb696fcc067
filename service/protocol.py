"""uvicorn's HTTP/1.1 protocol with a time limit on each request's head (slow clients).

uvicorn closes idle keep-alive connections (``--timeout-keep-alive``), but once a byte of a
request has arrived nothing limits how long the rest of its head may take: a client sending one
byte per second holds its connection (and a file handle) for as long as it likes, and enough of
them exhaust the server. :class:`GuardedH11Protocol` starts a timer when a connection opens and
again after each answer; if the request line and headers are not complete within
``LINKAGE_HEADER_TIMEOUT_S``, the client gets a ``408`` problem (when it has sent part of a
head) and the connection is closed. The body's own limit (``LINKAGE_BODY_TIMEOUT_S``) is kept by
:class:`service.middleware.RequestContext`, so it holds under any server.

Use it with ``uvicorn service.main:app --http service.protocol:GuardedH11Protocol`` (the
README's start command and the Dockerfile do).
"""

from __future__ import annotations

import asyncio
import json
import logging
from typing import Any

import h11
from uvicorn.protocols.http.h11_impl import H11Protocol

from service.config import get_settings

log = logging.getLogger("service.access")


def _response_408(timeout: float) -> bytes:
    body = json.dumps({
        "type": "/problems/header-timeout",
        "title": "Request head too slow",
        "status": 408,
        "detail": f"the request line and headers did not arrive within "
                  f"LINKAGE_HEADER_TIMEOUT_S = {timeout:g} s",
        "errors": [],
    }).encode()
    head = (
        "HTTP/1.1 408 Request Timeout\r\n"
        "content-type: application/problem+json\r\n"
        f"content-length: {len(body)}\r\n"
        "connection: close\r\n\r\n"
    ).encode()
    return head + body


class GuardedH11Protocol(H11Protocol):
    """``H11Protocol`` whose request heads must arrive within ``LINKAGE_HEADER_TIMEOUT_S``."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.header_timeout = get_settings().header_timeout_s
        self._head_timer: asyncio.TimerHandle | None = None

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        self._arm()

    def connection_lost(self, exc: Exception | None) -> None:
        self._disarm()
        super().connection_lost(exc)

    def handle_events(self) -> None:
        super().handle_events()
        if self.conn.their_state is not h11.IDLE:  # the head is complete (or broken)
            self._disarm()

    def on_response_complete(self) -> None:
        super().on_response_complete()
        if not self.transport.is_closing() and self.conn.their_state is h11.IDLE:
            self._arm()  # the next request's head, on a kept-alive connection

    def _arm(self) -> None:
        self._disarm()
        self._head_timer = self.loop.call_later(self.header_timeout, self._head_timed_out)

    def _disarm(self) -> None:
        if self._head_timer is not None:
            self._head_timer.cancel()
            self._head_timer = None

    def _head_timed_out(self) -> None:
        self._head_timer = None
        if self.transport.is_closing() or self.conn.their_state is not h11.IDLE:
            return
        partial, _ = self.conn.trailing_data
        if partial:
            # h11 cannot answer a request it has not parsed; the bytes are written directly.
            self.transport.write(_response_408(self.header_timeout))
            log.info(json.dumps({
                "request_id": None, "method": None, "route": None, "path": None,
                "status": 408, "duration_ms": round(1e3 * self.header_timeout, 2),
                "client": f"{self.client[0]}:{self.client[1]}" if self.client else None,
            }))
        self.transport.close()
