"""Errors a user can cause.  The CLI prints them as one line and exits non-zero."""


class LampfabError(Exception):
    """A problem with the user's input or settings; the message says what and where."""


class CheckFailed(LampfabError):
    """A fabrication check failed; carries the checks' evidence (see checks.json)."""

    def __init__(self, message: str, failed: list):
        super().__init__(message)
        self.failed = failed


class GeometryError(LampfabError):
    """A geometry kernel (manifold3d, OCCT) returned a bad status or an invalid shape."""
