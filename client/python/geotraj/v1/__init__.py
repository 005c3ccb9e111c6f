"""The generated stubs of proto/geotraj/v1/geotraj.proto: `geotraj_pb2` (the messages) and
`geotraj_pb2_grpc` (TrajectoryServiceStub) (geotraj/_stubs.py: where they are found)."""
from .._stubs import extend_path as _extend_path

_extend_path(__path__, __path__[0], "geotraj/v1", "geotraj_pb2.py")
