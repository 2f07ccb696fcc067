"""What the sync and async clients share: the calls, the retry rule, problems to exceptions."""

from __future__ import annotations

import email.utils
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

import httpx

from linkage_client.errors import ProblemError

T = TypeVar("T")

#: Answers worth asking again after the server's ``Retry-After`` (busy, worker lost, ...).
RETRY_STATUSES = frozenset({503})


@dataclass(frozen=True)
class Call(Generic[T]):
    """One operation: method, path, body or query, and how to read a successful answer."""

    method: str
    path: str
    parse: Callable[[httpx.Response], T]
    json: Any = None
    params: Mapping[str, Any] | None = None
    headers: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class RetryPolicy:
    """Retries of a 503 that carries ``Retry-After``, bounded in count and in time.

    Parameters
    ----------
    retries : int
        Extra attempts at most (0: never retry).
    max_wait_s : float
        Longest single wait: a larger ``Retry-After`` is not waited for (the problem is raised).
    total_wait_s : float
        Longest total waiting over all retries of one call.
    """

    retries: int = 3
    max_wait_s: float = 30.0
    total_wait_s: float = 60.0

    def wait_for(self, response: httpx.Response, attempt: int, waited_s: float) -> float | None:
        """Seconds to wait before attempt ``attempt + 1``, or None to give up."""
        if response.status_code not in RETRY_STATUSES or attempt >= self.retries:
            return None
        delay = retry_after(response)
        if delay is None or delay > self.max_wait_s or waited_s + delay > self.total_wait_s:
            return None
        return delay


def retry_after(response: httpx.Response) -> float | None:
    """``Retry-After`` in seconds (delta-seconds or an HTTP date), None when absent or bad."""
    value = response.headers.get("retry-after")
    if value is None:
        return None
    value = value.strip()
    if value.isdigit():
        return float(value)
    try:
        when = email.utils.parsedate_to_datetime(value)
    except (TypeError, ValueError):
        return None
    return max(0.0, when.timestamp() - time.time())


def raise_for_problem(response: httpx.Response) -> None:
    """Raise ``ProblemError`` for any 4xx/5xx answer, with the problem document's fields."""
    if response.status_code < 400:
        return
    body: Mapping[str, Any]
    try:
        decoded = response.json()
        body = decoded if isinstance(decoded, Mapping) else {"detail": str(decoded)}
    except ValueError:  # not JSON (a proxy's page): keep its start
        body = {"title": response.reason_phrase, "detail": response.text[:1000]}
    body = {"status": response.status_code, **body}
    raise ProblemError(response.status_code, body, retry_after(response))


def json_of(response: httpx.Response) -> Any:
    return response.json()


def text_of(response: httpx.Response) -> str:
    return response.text


def bytes_of(response: httpx.Response) -> bytes:
    return response.content


def model(parse: Callable[[Any], T]) -> Callable[[httpx.Response], T]:
    """A parser that builds ``parse(json)`` from the answer."""
    return lambda response: parse(response.json())


def drop_none(body: Mapping[str, Any]) -> dict[str, Any]:
    """A request body without its unset (None) members."""
    return {k: v for k, v in body.items() if v is not None}
