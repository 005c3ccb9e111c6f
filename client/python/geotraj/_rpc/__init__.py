"""The generated stubs of google/rpc/status.proto and google/rpc/error_details.proto
(`status_pb2`, `error_details_pb2`): the error details geotrajd sends (geotraj/_stubs.py:
where they are found)."""
from .._stubs import extend_path as _extend_path

_extend_path(__path__, __path__[0], "google/rpc", "status_pb2.py")
