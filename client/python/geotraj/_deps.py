"""The check that `import geotraj` makes first: each third-party module the package needs,
with what to install when it is missing, so that the error says that rather than failing
deep inside a generated stub."""
import importlib

# (module, what it is, Debian package, pip requirement)
REQUIRED = (
    ("grpc", "gRPC for Python", "python3-grpcio", "grpcio"),
    ("google.protobuf", "Protocol Buffers for Python", "python3-protobuf", "protobuf>=3.20"),
    ("numpy", "NumPy", "python3-numpy", "numpy"),
)

HOW = ("On Debian or Ubuntu: sudo apt-get install {deb}, then use /usr/bin/python3, or a venv made with "
       "`/usr/bin/python3 -m venv --system-site-packages` (a venv without it does not see Debian's packages). "
       "Elsewhere: pip install '{pip}'.")


def missing_dependency(module, what, deb, pip, cause):
    """The ImportError for a required module that cannot be imported."""
    return ImportError(f"geotraj needs {what} (the Python module `{module}`), which cannot be imported here "
                       f"({type(cause).__name__}: {cause}). " + HOW.format(deb=deb, pip=pip), name=module)


def check():
    """Imports every required module; raises the first missing one's ImportError."""
    for module, what, deb, pip in REQUIRED:
        try:
            importlib.import_module(module)
        except ImportError as e:
            raise missing_dependency(module, what, deb, pip, e) from None
    from google import protobuf
    version = tuple(int(x) for x in protobuf.__version__.split(".")[:2] if x.isdigit())
    if version < (3, 20):
        raise ImportError(f"geotraj needs protobuf 3.20 or later (its generated stubs use "
                          f"google.protobuf.internal.builder); this Python has {protobuf.__version__}. "
                          + HOW.format(deb="python3-protobuf", pip="protobuf>=3.20"), name="google.protobuf")
