"""The generated modules, and requests given as a message, a dict or a JSON file."""
import json
import os
from typing import Any, Mapping, Type, TypeVar, Union

from google.protobuf import json_format
from google.protobuf.message import Message

try:
    from .v1 import geotraj_pb2 as pb
    from .v1 import geotraj_pb2_grpc as pb_grpc
except ImportError as e:
    raise ImportError(
        f"geotraj: the generated gRPC stubs are missing ({e}). An installed package has them "
        "(pip install ./client/python generates them while it builds). From the source tree, "
        "generate them into client/python/gen as client/python/README.md says, or point "
        "$GEOTRAJ_PY_STUBS at a directory that has geotraj/v1/geotraj_pb2.py "
        "(a build tree's tests/interop/pystubs).", name="geotraj.v1.geotraj_pb2") from None

try:  # google.rpc of googleapis-common-protos, when this Python has it: one module per .proto
    from google.rpc import error_details_pb2, status_pb2
except ImportError:
    try:
        from ._rpc import error_details_pb2, status_pb2
    except ImportError as e:
        raise ImportError(f"geotraj: the generated stubs of google/rpc/status.proto and error_details.proto "
                          f"are missing ({e}); they are generated with geotraj.proto's (client/python/README.md)",
                          name="geotraj._rpc.status_pb2") from None

__all__ = ["pb", "pb_grpc", "status_pb2", "error_details_pb2", "RequestLike", "as_message", "to_dict", "enum_name"]

M = TypeVar("M", bound=Message)
RequestLike = Union[Message, Mapping[str, Any], str, "os.PathLike[str]"]


def as_message(request: Any, cls: Type[M], what: str = "request") -> M:
    """`request` as a `cls` message: the message itself (not copied), a dict in the proto JSON
    mapping (camelCase or the proto's own field names), or the path of a JSON file holding one
    (client/grpcurl/*.json). ValueError names the file and the field that does not parse."""
    if isinstance(request, cls):
        return request
    name = cls.DESCRIPTOR.full_name
    if isinstance(request, Message):
        raise TypeError(f"{what}: a {name} is expected, got a {request.DESCRIPTOR.full_name}")
    if isinstance(request, Mapping):
        try:
            return json_format.ParseDict(request, cls())
        except json_format.ParseError as e:
            raise ValueError(f"{what}: not a {name} in the proto JSON mapping: {e}") from None
    if isinstance(request, (str, os.PathLike)):
        path = os.fspath(request)
        with open(path, encoding="utf-8") as f:
            text = f.read()
        try:
            return json_format.Parse(text, cls())
        except json_format.ParseError as e:
            raise ValueError(f"{path}: not a {name} in the proto JSON mapping: {e}") from None
    raise TypeError(f"{what}: a {name}, a dict in its JSON mapping or the path of a JSON file is expected, "
                    f"got {type(request).__name__}")


def to_dict(message: Message) -> dict:
    """A message in the proto JSON mapping (camelCase names), as json.loads would give it."""
    return json.loads(json_format.MessageToJson(message))


def enum_name(message: Message, field: str) -> str:
    """The name of an enum field's value (`LIVE_STATE_RUNNING`)."""
    enum = message.DESCRIPTOR.fields_by_name[field].enum_type
    value = getattr(message, field)
    return enum.values_by_number[value].name if value in enum.values_by_number else str(value)
