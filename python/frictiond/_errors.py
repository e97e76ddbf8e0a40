"""Exceptions of the frictiond package (raised from the C++ client library)."""

from typing import Any, Optional


class DaemonError(RuntimeError):
    """The daemon answered with an error, or could not be reached.

    Attributes:
        status: HTTP status (0 when no daemon answered).
        error: the daemon's error code (e.g. "invalid_argument"), or None.
        field: the request field the daemon rejected (e.g. "fn_n"), or None.
        detail: the daemon's message, or None.
        body: the whole JSON error body as Python objects (for an unknown
            material it holds the identification request and stroke plan),
            or None.
    """

    def __init__(self, message: str, status: int = 0, error: Optional[str] = None,
                 field: Optional[str] = None, detail: Optional[str] = None,
                 body: Any = None) -> None:
        super().__init__(message)
        self.status = status
        self.error = error
        self.field = field
        self.detail = detail
        self.body = body


class NotFoundError(DaemonError, LookupError):
    """HTTP 404: unknown material, fingertip or version. For an unknown
    material, body["identification"] is the request the daemon recorded."""


class UnreachableError(DaemonError, ConnectionError):
    """No daemon answered (status 0) and no cached model could serve."""
