"""Builds the geotraj package: its metadata is in pyproject.toml; this file adds the step that
generates the gRPC stubs while the package is built.

build_py runs protoc and grpc_python_plugin (Debian: protobuf-compiler and
protobuf-compiler-grpc, which `make deps` installs) on

  proto/geotraj/v1/geotraj.proto          -> geotraj/v1/geotraj_pb2.py, geotraj_pb2_grpc.py
  google/rpc/status.proto                 -> geotraj/_rpc/status_pb2.py
  google/rpc/error_details.proto          -> geotraj/_rpc/error_details_pb2.py

The generated geotraj_pb2_grpc.py imports `from geotraj.v1 import geotraj_pb2`, which the
package's own layout resolves (geotraj.v1 is a subpackage), so no generated file is edited.

Where the .proto files are looked for, first found wins:
  geotraj.proto:     $GEOTRAJ_PROTO_DIR, then the repository's proto/ (../../proto from here)
  google/rpc/*.proto: $GEOTRAJ_GOOGLEAPIS_DIR, then
                     /usr/share/gocode/src/github.com/gogo/googleapis (golang-github-gogo-googleapis-dev)
The tools: $PROTOC, else protoc on PATH; $GRPC_PYTHON_PLUGIN, else grpc_python_plugin on PATH.
"""
import os
import shutil
import subprocess
import tempfile

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = os.path.dirname(os.path.abspath(__file__))
DEBIAN_GOOGLEAPIS = "/usr/share/gocode/src/github.com/gogo/googleapis"
GEOTRAJ_PROTO = "geotraj/v1/geotraj.proto"
RPC_PROTOS = ("google/rpc/status.proto", "google/rpc/error_details.proto")


def _find_dir(what, env, candidates, relative):
    """The first of $env and the candidates that holds `relative`; SystemExit naming them all."""
    tried = []
    for d in ([os.environ[env]] if os.environ.get(env) else []) + list(candidates):
        tried.append(d)
        if os.path.isfile(os.path.join(d, relative)):
            return d
    raise SystemExit(f"geotraj: cannot generate the gRPC stubs: {relative} ({what}) is in none of "
                     f"{', '.join(tried)}; set {env} to the directory that holds it")


def _find_tool(env, name, debian_package):
    path = os.environ.get(env) or shutil.which(name)
    if not path or not os.path.isfile(path):
        raise SystemExit(f"geotraj: cannot generate the gRPC stubs: {name} not found (Debian: apt-get install "
                         f"{debian_package}, which `make deps` installs; or set {env} to its path)")
    return path


def generate_stubs(package_root):
    """Writes the stubs into package_root/geotraj/v1 and package_root/geotraj/_rpc."""
    proto_dir = _find_dir("the geotraj API", "GEOTRAJ_PROTO_DIR",
                          [os.path.normpath(os.path.join(HERE, "..", "..", "proto"))], GEOTRAJ_PROTO)
    rpc_dir = _find_dir("google.rpc's error details", "GEOTRAJ_GOOGLEAPIS_DIR", [DEBIAN_GOOGLEAPIS], RPC_PROTOS[1])
    protoc = _find_tool("PROTOC", "protoc", "protobuf-compiler")
    plugin = _find_tool("GRPC_PYTHON_PLUGIN", "grpc_python_plugin", "protobuf-compiler-grpc")
    with tempfile.TemporaryDirectory() as out:
        cmd = [protoc, f"-I{proto_dir}", f"-I{rpc_dir}", f"--python_out={out}", f"--grpc_out={out}",
               f"--plugin=protoc-gen-grpc={plugin}", os.path.join(proto_dir, GEOTRAJ_PROTO),
               *(os.path.join(rpc_dir, p) for p in RPC_PROTOS)]
        result = subprocess.run(cmd, capture_output=True, text=True)
        if result.returncode != 0:
            raise SystemExit(f"geotraj: protoc failed ({' '.join(cmd)}):\n{result.stderr}")
        written = []
        for src, dst in (("geotraj/v1/geotraj_pb2.py", "geotraj/v1/geotraj_pb2.py"),
                         ("geotraj/v1/geotraj_pb2_grpc.py", "geotraj/v1/geotraj_pb2_grpc.py"),
                         ("google/rpc/status_pb2.py", "geotraj/_rpc/status_pb2.py"),
                         ("google/rpc/error_details_pb2.py", "geotraj/_rpc/error_details_pb2.py")):
            target = os.path.join(package_root, dst)
            os.makedirs(os.path.dirname(target), exist_ok=True)
            shutil.copyfile(os.path.join(out, src), target)
            written.append(target)
    return written


class BuildPyWithStubs(build_py):
    """build_py, then the generated stubs into the build directory (an editable install: into
    the source tree, where the editable import path finds them; .gitignore lists them)."""

    def run(self):
        super().run()
        root = HERE if getattr(self, "editable_mode", False) else self.build_lib
        for path in generate_stubs(root):
            self.announce(f"generated {os.path.relpath(path, root)}", level=2)

    def get_outputs(self, include_bytecode=True):
        # The generated modules belong to the wheel's record of what was built.
        outputs = super().get_outputs(include_bytecode)
        extra = [os.path.join(self.build_lib, p) for p in
                 ("geotraj/v1/geotraj_pb2.py", "geotraj/v1/geotraj_pb2_grpc.py",
                  "geotraj/_rpc/status_pb2.py", "geotraj/_rpc/error_details_pb2.py")]
        return outputs + [p for p in extra if p not in outputs]


def version():
    scope = {}
    with open(os.path.join(HERE, "geotraj", "_version.py"), encoding="utf-8") as f:
        exec(f.read(), scope)
    return scope["__version__"]


setup(version=version(), packages=["geotraj", "geotraj.v1", "geotraj._rpc"],
      package_data={"geotraj": ["py.typed"]}, cmdclass={"build_py": BuildPyWithStubs})
