"""The package's version: the project's (CMakeLists.txt `project(geotraj VERSION ...)`)."""
__version__ = "0.6.0"
