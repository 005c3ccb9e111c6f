#!/usr/bin/env python3
"""Writes a copy of a request (proto JSON) with some fields set.

Usage: request_with.py IN OUT FIELD=VALUE...
  FIELD  a dotted path of proto JSON names (path.unspecified, analysisPoints, optimize)
  VALUE  JSON (a number, an object, true) or, if it does not parse as JSON, a string
Only the Python standard library.
"""
import json
import sys


def main(argv):
    if len(argv) < 3:
        sys.exit(__doc__)
    with open(argv[1]) as f:
        request = json.load(f)
    for assignment in argv[3:]:
        field, sep, text = assignment.partition("=")
        if not sep or not field:
            sys.exit(f"request_with.py: '{assignment}' is not FIELD=VALUE")
        try:
            value = json.loads(text)
        except json.JSONDecodeError:
            value = text
        *parents, leaf = field.split(".")
        node = request
        for name in parents:
            node = node.setdefault(name, {})
        node[leaf] = value
    with open(argv[2], "w") as f:
        json.dump(request, f)


if __name__ == "__main__":
    main(sys.argv)
