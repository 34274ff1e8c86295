"""FulcrumError: the one exception the package raises for a refused or failed call.

The server names the field at fault at the start of its message
("batch.edits[1].set_velocity.linear: must be finite"); FulcrumError splits
that off with the same rule the server's log uses (server/src/stats.cpp,
field_of), so callers can branch on `field` without parsing text.
"""

import re

import grpc

# A field path: letters, digits, '_', '.', '[' and ']' before the first ": ".
_FIELD = re.compile(r"^([A-Za-z0-9_.\[\]]+): ")


def field_of(message):
    """The field a server message names ("world_id: no world 7" -> "world_id"), or ""."""
    match = _FIELD.match(message or "")
    return match.group(1) if match else ""


class FulcrumError(Exception):
    """A call the server refused, a connection that failed, or input refused before sending.

    Attributes:
        code: a grpc.StatusCode (INVALID_ARGUMENT, NOT_FOUND, FAILED_PRECONDITION, ...).
        field: the field path the message names ("batch.edits[0].set_velocity.body"),
            or "" when it names none (connection errors, for instance).
        message: the whole message, field included, as the server wrote it.
    """

    def __init__(self, code, message, field=None):
        self.code = code
        self.message = message
        self.field = field_of(message) if field is None else field
        super().__init__(f"{code.name}: {message}")

    @property
    def code_name(self):
        """The code's name, e.g. "INVALID_ARGUMENT"."""
        return self.code.name

    @classmethod
    def from_rpc(cls, error):
        """Converts a grpc.RpcError (every call's failure) into a FulcrumError."""
        code = error.code() if hasattr(error, "code") else grpc.StatusCode.UNKNOWN
        details = error.details() if hasattr(error, "details") else str(error)
        return cls(code or grpc.StatusCode.UNKNOWN, details or "")


def invalid_argument(field, message):
    """A FulcrumError for input refused before it is sent, worded as the server would."""
    return FulcrumError(grpc.StatusCode.INVALID_ARGUMENT, f"{field}: {message}", field)
