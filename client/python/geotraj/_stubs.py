"""Where a subpackage of generated stubs finds them when they were not generated into it: an
installed package has them in place (setup.py generates them while it is built); run from the
source tree, they are looked for in $GEOTRAJ_PY_STUBS and then client/python/gen, the layout
protoc writes (client/python/README.md)."""
import os


def extend_path(path, package_dir, relative, marker):
    """Appends to the subpackage's __path__ `path` the directory `relative` of the first stubs
    root that holds `relative`/`marker`, unless `marker` is in `package_dir` already."""
    if os.path.isfile(os.path.join(package_dir, marker)):
        return
    source_gen = os.path.join(os.path.dirname(os.path.dirname(package_dir)), "gen")
    for root in (os.environ.get("GEOTRAJ_PY_STUBS"), source_gen):
        if root and os.path.isfile(os.path.join(root, relative, marker)):
            path.append(os.path.join(root, relative))
            return
