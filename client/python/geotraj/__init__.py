"""geotraj: the Python client of geotrajd, the geotraj trajectory service for robot
manipulators (gRPC, proto/geotraj/v1/geotraj.proto).

    import geotraj
    with geotraj.Client("127.0.0.1:50051") as client:
        plan = client.plan("client/grpcurl/plan_demo_path_a.json")
        samples = client.stream("client/grpcurl/plan_demo_path_a.json")
        samples.write_csv("path_a.csv")

Units SI (m, s, rad), vectors and poses in the world frame W, quaternions (w, x, y, z),
indices zero-based. Failures raise GeotrajError (code, message, field_violations,
precondition_violations). The generated messages are geotraj.pb (geotraj.v1.geotraj_pb2).
"""
from ._version import __version__
from . import _deps

_deps.check()  # an ImportError that says what to install, before anything needs it

from ._proto import as_message, pb, pb_grpc, to_dict  # noqa: E402
from .client import (DEFAULT_ADDRESS, HEARTBEAT_S, Client, Execution, ForwardKinematics,  # noqa: E402
                     InverseKinematics, Jogging, LiveCall, Profile)
from .errors import FieldViolation, GeotrajError, PreconditionViolation  # noqa: E402
from .samples import CSV_COLUMNS, CsvWriter, Samples, csv_header, has_steps  # noqa: E402

__all__ = [
    "__version__", "Client", "Execution", "Jogging", "LiveCall", "ForwardKinematics", "InverseKinematics",
    "Profile", "Samples", "CsvWriter", "CSV_COLUMNS", "csv_header", "has_steps", "GeotrajError",
    "FieldViolation", "PreconditionViolation", "pb", "pb_grpc", "as_message", "to_dict",
    "DEFAULT_ADDRESS", "HEARTBEAT_S",
]
