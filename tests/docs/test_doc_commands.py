#!/usr/bin/python3
"""The command transcripts of the documentation, run and compared with what they print.

A transcript is a fenced block right after an HTML comment `<!-- doc-test [OPTIONS] -->`.
Its lines that start with `$ ` are commands (a trailing backslash continues one on the next
line); the lines after a command, up to the next command, are what it prints:

    <!-- doc-test server exit=1 stderr -->
    ```text
    $ build/client/geotraj --server 127.0.0.1:50051 plan client/grpcurl/bad_request.json
    geotraj: INVALID_ARGUMENT: invalid request: 4 problems: ...
      path.frames[1].torsion: torsion is undefined where curvature is 0 (give a curvature > 0)
    ...
    ```

Each command runs in bash from the repository's root, `build/client/geotraj` (or a bare
`geotraj`), `build/server/geotrajd` (or `geotrajd`) and `node` replaced by the binaries
given here, any other `build/` path taken in the build directory, and `127.0.0.1:50051`
replaced by the address of a geotrajd that this harness starts on a free port.

The printed lines are compared with the block's:
- whitespace is normalised; text must be equal;
- numbers agree to the digits the document prints (half a unit in its last digit), or within
  `rel=R` (relative) or `abs=A` when the block's options give them;
- a line `...` stands for any number of lines (at the end: the rest of the output is not
  shown); `...` within a line for any text there;
- lines that match the option `text-only=REGEX` are compared without their numbers (what
  real time decides: a live call's timing).

Options: `server` (needs the geotrajd), `npm` (needs node and the npm packages that the build
installs; skipped, saying so, when this harness is given --no-npm REASON), `exit=N` (every
command's exit status, default 0), `stderr` (standard error is part of the output, after
2>&1), `timeout=S` (per command, default 30), `rel=R`, `abs=A`, `text-only=REGEX`. The
commands run without the caller's GEOTRAJ_* variables. Commands that need a browser, TLS
certificates, Docker or Kubernetes are shown without `$ ` and not marked; a fenced block
whose first line is a `$ ` command must have the marker.

Besides the transcripts: every docs/*.md is listed in README.md's Layout section (and every
file the section lists exists), and each document of --require has at least one transcript.

    test_doc_commands.py --source-dir . --geotraj build/client/geotraj \
        --geotrajd build/server/geotrajd --build-dir build [--node node] [--node-path DIR]
"""

import argparse
import concurrent.futures
import glob
import math
import os
import re
import shlex
import subprocess
import sys
import tempfile
import threading
import time

DEFAULT_DOCS = ["README.md", "client/node/README.md", "client/python/README.md", "docs/*.md"]
DEFAULT_REQUIRED = ["README.md", "client/node/README.md", "client/python/README.md", "docs/clients.md",
                    "docs/moves.md"]
DOC_ADDRESS = "127.0.0.1:50051"
MARKER = re.compile(r"^\s*<!--\s*doc-test\b(.*?)-->\s*$")
FENCE = re.compile(r"^(\s*)(`{3,}|~{3,})")
NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
TOKEN = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[^\s\d.+-]+|[.+-]")


class Block:
    def __init__(self, doc, line, options, lines):
        self.doc = doc
        self.line = line          # line number of the fence's first content line
        self.options = options
        self.lines = lines        # the block's content lines, with their line numbers

    def where(self, offset=0):
        return f"{self.doc}:{self.line + offset}"


def parse_options(text, where):
    options = {"server": False, "stderr": False, "npm": False, "exit": 0, "timeout": 30.0,
               "rel": 0.0, "abs": 0.0, "text-only": None}
    for word in shlex.split(text):
        key, _, value = word.partition("=")
        if key in ("server", "stderr", "npm") and not value:
            options[key] = True
        elif key == "exit":
            options[key] = int(value)
        elif key in ("timeout", "rel", "abs"):
            options[key] = float(value)
        elif key == "text-only":
            options[key] = re.compile(value)
        else:
            raise ValueError(f"{where}: unknown doc-test option {word!r}")
    return options


def read_fence(lines, j):
    """(content [(line number, text)], index of the closing fence) of the block opening at j."""
    fence = FENCE.match(lines[j])
    indent, ticks = fence.group(1), fence.group(2)
    k = j + 1
    content = []
    while k < len(lines) and not lines[k].strip().startswith(ticks):
        text = lines[k][len(indent):] if lines[k].startswith(indent) else lines[k].lstrip()
        content.append((k + 1, text))
        k += 1
    return content, k


def read_blocks(root, doc):
    """The doc-test blocks of a document. A fenced block that reads as a transcript (its first
    line a `$ ` command) without the marker is an error: mark it, or show the commands alone."""
    path = os.path.join(root, doc)
    with open(path, encoding="utf-8") as f:
        lines = f.read().split("\n")
    blocks = []
    i = 0
    while i < len(lines):
        m = MARKER.match(lines[i])
        if FENCE.match(lines[i]):  # a block without a marker
            content, k = read_fence(lines, i)
            first = next((t for _, t in content if t.strip()), "")
            if first.startswith("$ "):
                raise ValueError(f"{doc}:{i + 1}: a transcript (`$ ` lines) without a doc-test marker")
            i = k + 1
            continue
        if not m:
            i += 1
            continue
        where = f"{doc}:{i + 1}"
        options = parse_options(m.group(1), where)
        j = i + 1
        while j < len(lines) and not lines[j].strip():
            j += 1
        if j >= len(lines) or not FENCE.match(lines[j]):
            raise ValueError(f"{where}: a doc-test marker must be followed by a fenced block")
        content, k = read_fence(lines, j)
        if k == len(lines):
            raise ValueError(f"{where}: the block after the doc-test marker is not closed")
        blocks.append(Block(doc, j + 2, options, content))
        i = k + 1
    return blocks


def transcript(block):
    """[(line, command, [(line, expected output line)])] of a block."""
    steps = []
    lines = list(block.lines)
    i = 0
    while i < len(lines):
        number, text = lines[i]
        if not text.startswith("$ "):
            if not steps:
                raise ValueError(f"{block.doc}:{number}: a transcript starts with a `$ ` command line")
            steps[-1][2].append((number, text))
            i += 1
            continue
        command = text[2:]
        while command.endswith("\\") and i + 1 < len(lines):
            i += 1
            command = command[:-1] + " " + lines[i][1].lstrip("> ").strip()
        steps.append((number, command, []))
        i += 1
    for step in steps:  # blank lines that close a block belong to no output
        while step[2] and not step[2][-1][1].strip():
            step[2].pop()
    return steps


# --- comparing lines -------------------------------------------------------------------------

def tokens(text):
    out = []
    for m in TOKEN.finditer(text):
        s = m.group(0)
        if NUMBER.fullmatch(s) and any(c.isdigit() for c in s):
            out.append(("n", s))
        else:
            out.append(("t", s))
    # Adjacent text pieces (`.` and `-` are split off numbers) are joined back so that text
    # compares as text.
    merged = []
    for kind, s in out:
        if merged and kind == "t" and merged[-1][0] == "t" and not s.isspace():
            merged[-1] = ("t", merged[-1][1] + "\x00" + s)
        else:
            merged.append((kind, s))
    return merged


def tolerance(expected, options):
    mantissa, _, exponent = expected.lower().partition("e")
    decimals = len(mantissa.partition(".")[2])
    scale = 10.0 ** (int(exponent or 0) - decimals)
    value = abs(float(expected))
    return max(0.5 * scale * (1 + 1e-9) + 1e-12 * value, options["rel"] * value, options["abs"])


def same_token(expected, actual, options, numbers, mode="="):
    """mode "=": equal; "prefix": actual starts with expected; "suffix": actual ends with it."""
    ek, es = expected
    ak, as_ = actual
    if ek == "n" and ak == "n":
        if not numbers:
            return None
        diff = abs(float(es) - float(as_))
        tol = tolerance(es, options)
        if diff <= tol or (math.isnan(float(es)) and math.isnan(float(as_))):
            return None
        return f"{es} in the document, {as_} printed (tolerance {tol:.3g})"
    if ek != ak:
        return f"`{es.replace(chr(0), ' ')}` in the document, `{as_.replace(chr(0), ' ')}` printed"
    e, a = es.replace("\x00", ""), as_.replace("\x00", "")
    ok = {"=": es == as_, "prefix": a.startswith(e), "suffix": a.endswith(e), "inside": e in a}[mode]
    return None if ok else f"`{es.replace(chr(0), ' ')}` in the document, `{as_.replace(chr(0), ' ')}` printed"


def match_group(group, actual, start, options, numbers, first_partial, last_partial):
    """The first difference of group against actual[start:], or None. A partial end (next to
    an elision) may match a text token in part: its end first, its start last."""
    if start + len(group) > len(actual):
        return "the printed line is shorter"
    for k, tok in enumerate(group):
        first = k == 0 and first_partial
        last = k == len(group) - 1 and last_partial
        mode = "inside" if first and last else "suffix" if first else "prefix" if last else "="
        err = same_token(tok, actual[start + k], options, numbers, mode)
        if err:
            return err
    return None


def line_difference(expected, actual, options):
    """None when the printed line `actual` is the document's line `expected`, else why not."""
    numbers = not (options["text-only"] and options["text-only"].search(expected))
    parts = [tokens(p) for p in expected.split("...")]
    got = tokens(actual)
    if len(parts) == 1:
        if len(parts[0]) != len(got):
            # Say where they part.
            for k in range(min(len(parts[0]), len(got))):
                err = same_token(parts[0][k], got[k], options, numbers)
                if err:
                    return err
            return "the lines have different lengths"
        return match_group(parts[0], got, 0, options, numbers, False, False)
    pos = 0
    for index, group in enumerate(parts):
        first_partial = index > 0
        last_partial = index < len(parts) - 1
        if not group:
            continue
        if index == 0:
            err = match_group(group, got, 0, options, numbers, False, last_partial)
            if err:
                return err
            pos = len(group)
            continue
        if index == len(parts) - 1:
            at = len(got) - len(group)
            if at < pos:
                return "the printed line is shorter"
            err = match_group(group, got, at, options, numbers, True, False)
            if err:
                return err
            pos = len(got)
            continue
        found = False
        first_error = None
        for at in range(pos, len(got) - len(group) + 1):
            err = match_group(group, got, at, options, numbers, True, True)
            if err is None:
                pos = at + len(group)
                found = True
                break
            first_error = first_error or err
        if not found:
            return first_error or "the printed line is shorter"
    return None


def output_difference(command_line, expected, actual_text, options):
    """None when the printed text matches the expected lines, else (line number, message)."""
    actual = actual_text.split("\n")
    while actual and not actual[-1].strip():
        actual.pop()
    j = 0
    skipping = False
    for number, line in expected:
        if line.strip() == "...":
            skipping = True
            continue
        if skipping:
            for k in range(j, len(actual)):
                if line_difference(line, actual[k], options) is None:
                    j = k + 1
                    break
            else:
                # The nearest candidate: the first line of the same text, its numbers aside.
                loose = dict(options, **{"text-only": re.compile("")})
                for k in range(j, len(actual)):
                    if line_difference(line, actual[k], loose) is None:
                        return number, (f"{line_difference(line, actual[k], options)}\n"
                                        f"    document: {line.strip()}\n    printed:  {actual[k].strip()}")
                return number, f"no printed line after line {j} is\n    {line.strip()}"
            skipping = False
            continue
        if j >= len(actual):
            return number, f"the output ended before\n    {line.strip()}"
        err = line_difference(line, actual[j], options)
        if err:
            return number, (f"{err}\n    document: {line.strip()}\n    printed:  {actual[j].strip()}")
        j += 1
    if not skipping and j < len(actual):
        return (expected[-1][0] if expected else command_line,
                f"more output than the document shows (end it with `...`):\n    printed:  {actual[j].strip()}")
    return None


# --- running ---------------------------------------------------------------------------------

def clean_environment():
    """The environment without GEOTRAJ_* variables: the documents show the defaults (a token,
    an address or a log level of the caller's would change what the commands print)."""
    return {k: v for k, v in os.environ.items() if not k.startswith("GEOTRAJ_")}


class Server:
    def __init__(self, geotrajd):
        self.geotrajd = geotrajd
        self.process = None
        self.address = None
        self.lock = threading.Lock()
        self.log = tempfile.TemporaryFile()

    def get(self):
        with self.lock:
            if self.address:
                return self.address
            env = dict(clean_environment(), GEOTRAJ_PLAINTEXT="true")
            self.process = subprocess.Popen([self.geotrajd, "--address", "127.0.0.1:0"],
                                            stdout=subprocess.PIPE, stderr=self.log,
                                            env=env, text=True)
            line = self.process.stdout.readline()
            m = re.search(r"\bon (\S+:\d+)", line)
            if not m:
                raise RuntimeError(f"geotrajd did not say where it serves: {line!r}")
            self.address = m.group(1)
            # Keep reading its standard output so that it never blocks on a full pipe.
            threading.Thread(target=self.process.stdout.read, daemon=True).start()
            return self.address

    def stop(self):
        if self.process and self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=40)
            except subprocess.TimeoutExpired:
                self.process.kill()


def substitute(command, args, address):
    def build_path(m):
        return m.group(1) + os.path.join(args.build_dir, m.group(2))
    command = re.sub(r"(^|[\s=(;|&])(?:build/client/|(?<![\w/.-]))geotraj(?![\w.-])",
                     lambda m: m.group(1) + args.geotraj, command)
    command = re.sub(r"(^|[\s=(;|&])(?:build/server/|(?<![\w/.-]))geotrajd(?![\w.-])",
                     lambda m: m.group(1) + args.geotrajd, command)
    command = re.sub(r"(^|[\s=(;|&])build/(\S+)", build_path, command)
    if address:
        command = command.replace(DOC_ADDRESS, address)
    return command


def run_block(block, args, server):
    """A list of failure messages of the block."""
    failures = []
    try:
        steps = transcript(block)
    except ValueError as e:
        return [str(e)]
    if not steps:
        return [f"{block.where()}: the doc-test block has no `$ ` command"]
    address = server.get() if block.options["server"] else None
    env = clean_environment()
    if args.node_path:
        env["NODE_PATH"] = args.node_path
    env["PATH"] = os.path.dirname(os.path.abspath(args.node)) + os.pathsep + env.get("PATH", "")
    for number, command, expected in steps:
        actual_command = substitute(command, args, address)
        if block.options["stderr"]:
            actual_command = f"{{ {actual_command} ; }} 2>&1"
        started = time.monotonic()
        try:
            done = subprocess.run(["bash", "-c", actual_command], cwd=args.source_dir, env=env,
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                  timeout=block.options["timeout"])
        except subprocess.TimeoutExpired:
            failures.append(f"{block.doc}:{number}: `{command}` ran longer than {block.options['timeout']} s")
            continue
        seconds = time.monotonic() - started
        if args.verbose:
            print(f"  {block.doc}:{number}: {seconds:.2f} s  {command}", flush=True)
        if done.returncode != block.options["exit"]:
            failures.append(f"{block.doc}:{number}: `{command}` exited {done.returncode}, the document "
                            f"says {block.options['exit']}\n  ran: {actual_command}\n"
                            f"  stderr: {done.stderr.strip()[-2000:]}")
            continue
        diff = output_difference(number, expected, done.stdout, block.options)
        if diff:
            line, message = diff
            failures.append(f"{block.doc}:{line}: `{command}` prints otherwise: {message}")
    return failures


def check_layout(root):
    """Every docs/*.md named in README.md's Layout section."""
    with open(os.path.join(root, "README.md"), encoding="utf-8") as f:
        text = f.read()
    m = re.search(r"^## Layout\s*$(.*?)(?=^## |\Z)", text, re.M | re.S)
    if not m:
        return ["README.md: no `## Layout` section"]
    layout = m.group(1)
    failures = []
    for path in sorted(glob.glob(os.path.join(root, "docs", "*.md"))):
        name = os.path.basename(path)
        if not re.search(r"(?<![\w/-])(?:docs/)?" + re.escape(name) + r"(?!\w)", layout):
            failures.append(f"README.md: the Layout section does not list docs/{name}")
    for name in re.findall(r"`(?:docs/)?([\w-]+\.md)`", layout):
        if not os.path.exists(os.path.join(root, "docs", name)):
            failures.append(f"README.md: the Layout section lists docs/{name}, which does not exist")
    return failures


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--source-dir", required=True)
    p.add_argument("--build-dir", required=True)
    p.add_argument("--geotraj", required=True)
    p.add_argument("--geotrajd", required=True)
    p.add_argument("--node", default="node")
    p.add_argument("--node-path", help="NODE_PATH for node (the build's node_modules)")
    p.add_argument("--no-npm", metavar="REASON",
                   help="the build has no npm packages (and why): transcripts marked npm are skipped")
    p.add_argument("--docs", nargs="*", default=DEFAULT_DOCS, help="documents (globs, from the source dir)")
    p.add_argument("--require", nargs="*", default=DEFAULT_REQUIRED,
                   help="documents that must hold at least one transcript")
    p.add_argument("--jobs", type=int, default=3)
    p.add_argument("-v", "--verbose", action="store_true")
    args = p.parse_args()
    args.source_dir = os.path.abspath(args.source_dir)
    args.build_dir = os.path.abspath(args.build_dir)
    args.geotraj = os.path.abspath(args.geotraj)
    args.geotrajd = os.path.abspath(args.geotrajd)
    if os.sep in args.node:
        args.node = os.path.abspath(args.node)
    else:
        import shutil
        args.node = shutil.which(args.node) or args.node

    started = time.monotonic()
    failures = check_layout(args.source_dir)
    docs = []
    for pattern in args.docs:
        docs += sorted(os.path.relpath(p, args.source_dir)
                       for p in glob.glob(os.path.join(args.source_dir, pattern)))
    blocks = []
    for doc in docs:
        try:
            blocks += read_blocks(args.source_dir, doc)
        except ValueError as e:
            failures.append(str(e))
    for doc in args.require:
        if not any(b.doc == doc for b in blocks):
            failures.append(f"{doc}: no doc-test transcript")

    skipped = [b for b in blocks if b.options["npm"] and args.no_npm]
    blocks = [b for b in blocks if b not in skipped]
    for b in skipped:
        print(f"SKIPPED {b.where()}: needs the npm packages, and {args.no_npm}")

    server = Server(args.geotrajd)
    try:
        # The longest first (live calls run in real time).
        order = sorted(blocks, key=lambda b: -b.options["timeout"])
        with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
            results = list(pool.map(lambda b: (b, run_block(b, args, server)), order))
    finally:
        server.stop()
    commands = 0
    for block, block_failures in results:
        commands += sum(1 for _, t in block.lines if t.startswith("$ "))
        failures += block_failures
    seconds = time.monotonic() - started
    for f in failures:
        print(f"FAIL {f}\n")
    print(f"doc-test: {len(blocks)} transcripts, {commands} commands in {len(docs)} documents, "
          f"{len(skipped)} skipped, {len(failures)} failures, {seconds:.1f} s")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
