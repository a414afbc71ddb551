"""The one exception type of the bgkmap Python client."""

from __future__ import annotations

import grpc

# google.rpc.Code value -> grpc.StatusCode (ScanAck.code carries the number).
_CODES = {code.value[0]: code for code in grpc.StatusCode}


def status_code(value: int) -> grpc.StatusCode:
    """The grpc.StatusCode of a google.rpc.Code number (UNKNOWN for numbers it does not know)."""
    return _CODES.get(int(value), grpc.StatusCode.UNKNOWN)


class BgkmapError(Exception):
    """A call failed: `code` is the gRPC status code, `message` the server's message.

    Every failure of the client is a BgkmapError: statuses answered by bgkmapd (its message names
    the field and the limit), transport failures (UNAVAILABLE, DEADLINE_EXCEEDED), input the
    client refuses before sending it (INVALID_ARGUMENT, like the server would) and malformed
    answers (DATA_LOSS)."""

    def __init__(self, code: grpc.StatusCode, message: str):
        super().__init__(f"{code.name}: {message}")
        self.code = code
        self.message = message

    @property
    def code_name(self) -> str:
        """The status code as text, e.g. "INVALID_ARGUMENT"."""
        return self.code.name

    @classmethod
    def from_rpc_error(cls, error: grpc.RpcError) -> "BgkmapError":
        code = error.code() if hasattr(error, "code") else grpc.StatusCode.UNKNOWN
        details = error.details() if hasattr(error, "details") else str(error)
        return cls(code or grpc.StatusCode.UNKNOWN, details or "")


def invalid_argument(message: str) -> BgkmapError:
    return BgkmapError(grpc.StatusCode.INVALID_ARGUMENT, message)


def malformed(what: str) -> BgkmapError:
    return BgkmapError(grpc.StatusCode.DATA_LOSS, "malformed server response: " + what)
