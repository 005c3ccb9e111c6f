"""GeotrajError: a call that geotrajd refused or that failed, with the error details of the
google.rpc.Status in the `grpc-status-details-bin` trailer."""
from typing import Iterable, List, NamedTuple, Optional, Tuple

import grpc

from ._proto import error_details_pb2, status_pb2


class FieldViolation(NamedTuple):
    """One google.rpc.BadRequest field violation: the field path in proto JSON names
    (`path.frames[2].torsion`) and what is wrong with it."""
    field: str
    description: str


class PreconditionViolation(NamedTuple):
    """One google.rpc.PreconditionFailure violation (a plan the robot cannot follow, a jerk
    beyond a limit, ...): its type, its subject and what is wrong."""
    type: str
    subject: str
    description: str


class GeotrajError(Exception):
    """A failed call.

    code: the grpc.StatusCode (INVALID_ARGUMENT for a bad request, FAILED_PRECONDITION,
        UNAVAILABLE when the server cannot be reached, DEADLINE_EXCEEDED, UNAUTHENTICATED, ...).
    message: the status message.
    field_violations: [(field, description)] from a google.rpc.BadRequest detail.
    precondition_violations: [(type, subject, description)] from a google.rpc.PreconditionFailure.
    stop_reason: for Execute and Jog, the trailer `geotraj-stop-reason` (deadman, drain,
        deadline, invalid; "" when absent).
    """

    def __init__(self, code: grpc.StatusCode, message: str,
                 field_violations: Iterable[Tuple[str, str]] = (),
                 precondition_violations: Iterable[Tuple[str, str, str]] = (),
                 stop_reason: str = "", status: Optional[status_pb2.Status] = None):
        self.code = code
        self.message = message
        self.field_violations: List[FieldViolation] = [FieldViolation(*v) for v in field_violations]
        self.precondition_violations: List[PreconditionViolation] = [
            PreconditionViolation(*v) for v in precondition_violations]
        self.stop_reason = stop_reason
        self.status = status
        super().__init__(self._text())

    @property
    def code_name(self) -> str:
        """The status code's name: "INVALID_ARGUMENT"."""
        return self.code.name if isinstance(self.code, grpc.StatusCode) else str(self.code)

    def _text(self) -> str:
        lines = [f"{self.code_name}: {self.message}"]
        lines += [f"  {v.field}: {v.description}" for v in self.field_violations]
        lines += [f"  [{v.type}] {v.subject}: {v.description}" for v in self.precondition_violations]
        return "\n".join(lines)

    def describe(self) -> str:
        """The error as the examples print it: `error: CODE: message`, then the field
        violations of a bad request or the violations of a failed precondition."""
        lines = [f"error: {self.code_name}: {self.message}"]
        if self.field_violations:
            lines.append("bad request, field violations:")
            lines += [f"  {v.field}: {v.description}" for v in self.field_violations]
        if self.precondition_violations:
            lines.append("precondition failure, violations:")
            lines += [f"  [{v.type}] {v.subject}: {v.description}" for v in self.precondition_violations]
        return "\n".join(lines)

    @classmethod
    def from_call(cls, call, stop_reason: Optional[str] = None) -> "GeotrajError":
        """From a finished call that failed (a grpc.RpcError, or a streaming call's object):
        its code, details and trailing metadata."""
        code, message = call.code(), call.details() or ""
        trailers = dict(call.trailing_metadata() or ())
        raw = trailers.get("grpc-status-details-bin")
        fields: List[Tuple[str, str]] = []
        preconditions: List[Tuple[str, str, str]] = []
        status = None
        if raw is not None:
            status = status_pb2.Status.FromString(raw)
            for detail in status.details:
                bad = error_details_pb2.BadRequest()
                failure = error_details_pb2.PreconditionFailure()
                if detail.Unpack(bad):
                    fields += [(v.field, v.description) for v in bad.field_violations]
                elif detail.Unpack(failure):
                    preconditions += [(v.type, v.subject, v.description) for v in failure.violations]
        if stop_reason is None:
            stop_reason = trailers.get("geotraj-stop-reason", "")
        return cls(code, message, fields, preconditions, stop_reason, status)
