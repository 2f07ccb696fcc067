"""Exceptions: problems answered by the service (RFC 9457) and jobs that did not finish well."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from linkage_client.models import Job


class ClientError(Exception):
    """Base of every exception this client raises."""


@dataclass(frozen=True)
class ProblemItem:
    """One entry of a problem's ``errors``: where (``loc``) and what (``msg``)."""

    loc: tuple[str | int, ...]
    msg: str


class ProblemError(ClientError):
    """An ``application/problem+json`` answer (or any 4xx/5xx) as an exception.

    Attributes
    ----------
    status : int
        The HTTP status.
    type, title, detail : str
        The RFC 9457 fields (``type`` is ``/problems/<kind>``).
    kind : str
        ``type`` without its ``/problems/`` prefix (``"invalid-linkage"``, ``"busy"``, ...).
    errors : list of ProblemItem
        For validation problems: the field (``loc``) and the message of each error.
    retry_after : float or None
        Seconds from the ``Retry-After`` header (503 ``busy`` and its kin), if any.
    body : dict
        The whole problem document (extension members included).
    """

    def __init__(self, status: int, body: Mapping[str, Any],
                 retry_after: float | None = None) -> None:
        self.status = status
        self.body = dict(body)
        self.type = str(body.get("type", "about:blank"))
        self.title = str(body.get("title", ""))
        self.detail = str(body.get("detail", ""))
        self.instance = body.get("instance")
        self.errors = [ProblemItem(tuple(e.get("loc", ())), str(e.get("msg", "")))
                       for e in body.get("errors", []) if isinstance(e, Mapping)]
        self.retry_after = retry_after
        super().__init__(f"{status} {self.title}: {self.detail}")

    @property
    def kind(self) -> str:
        return self.type.removeprefix("/problems/")


class JobFailed(ClientError):
    """A job ended ``failed`` (``job.error`` says why) or ``cancelled``."""

    def __init__(self, job: Job) -> None:
        self.job = job
        err = job.error
        super().__init__(f"job {job.id} {job.status}"
                         + (f": {err.title}: {err.detail}" if err else ""))


class JobCancelled(JobFailed):
    """The job was cancelled (by this client on a timeout or interrupt, or by anyone)."""


class JobTimeout(ClientError):
    """A job did not finish within the time the client was asked to wait (it was cancelled)."""

    def __init__(self, job: Job, waited_s: float) -> None:
        self.job = job
        super().__init__(f"job {job.id} not finished after {waited_s:.1f} s (cancelled)")
