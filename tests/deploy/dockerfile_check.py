#!/usr/bin/env python3
"""A lint of deploy/Dockerfile for what this project promises of its image, without an engine.

Own rules (always): two stages, `build` on debian:bookworm and `runtime` on
debian:bookworm-slim; the build stage runs scripts/install-deps.sh and scripts/build.sh;
COPY sources exist and are not excluded by deploy/Dockerfile.dockerignore; every apt-get
install has -y and --no-install-recommends, every apt-get update removes the lists in the
same RUN; nothing downloaded (ADD of a URL, curl, wget); the runtime stage installs only
deploy/runtime-packages.txt, runs as the numeric non-root user 65532, exposes 50051 and
9090, sets GEOTRAJ_ADDRESS, GEOTRAJ_METRICS_ADDRESS and GEOTRAJ_LOG_FORMAT, stops with
SIGTERM, has a HEALTHCHECK through the geotraj CLI, exec-form ENTRYPOINT (geotrajd is PID 1
and receives the signal), the OCI labels.

deploy/compose.yaml and compose.tls.yaml (no `docker compose config` here): geotrajd
read-only as 65532 with no capabilities, the image's healthcheck, a stop grace above the
drain, ports on loopback, mounted files present, secrets defined where used.

Then dockerfilelint (npm) when --dockerfilelint names it or it is on PATH, with its known
false positive removed: it rejects HEALTHCHECK --start-period (its option regex stops at the
dash), which Docker has accepted since 17.05.

usage: dockerfile_check.py SOURCE_DIR [--dockerfilelint PATH]
"""
import argparse
import fnmatch
import json
import os
import re
import shlex
import shutil
import subprocess
import sys

FAILURES = []


def fail(msg):
    FAILURES.append(msg)
    print(f"FAIL: {msg}", file=sys.stderr)


def instructions(text):
    """(line number, KEYWORD, arguments) with continuation lines joined and comments dropped."""
    out, buf, start = [], "", 0
    for no, line in enumerate(text.splitlines(), 1):
        stripped = line.strip()
        if not buf and (not stripped or stripped.startswith("#")):
            continue
        if buf and stripped.startswith("#"):
            continue  # a comment inside a continued instruction
        if not buf:
            start = no
        if line.rstrip().endswith("\\"):
            buf += line.rstrip()[:-1] + " "
            continue
        buf += line
        keyword, _, args = buf.strip().partition(" ")
        out.append((start, keyword.upper(), args.strip()))
        buf = ""
    return out


def stages(instrs):
    result, current = [], None
    for no, kw, args in instrs:
        if kw == "FROM":
            m = re.fullmatch(r"(?:--platform=\S+\s+)?(\S+)(?:\s+AS\s+(\S+))?", args, re.I)
            current = {"line": no, "image": m.group(1) if m else args, "name": (m.group(2) or "") if m else "",
                       "instrs": []}
            result.append(current)
        elif current is not None:
            current["instrs"].append((no, kw, args))
    return result


def dockerignore_patterns(path):
    if not os.path.exists(path):
        fail(f"{os.path.relpath(path)} is missing: the whole tree, build directories included, would be sent")
        return []
    pats = []
    for line in open(path):
        line = line.strip()
        if line and not line.startswith("#"):
            pats.append(line)
    return pats


def ignored(rel, patterns):
    result = False
    for pat in patterns:
        neg = pat.startswith("!")
        p = pat[1:] if neg else pat
        p = p.rstrip("/")
        parts = rel.split("/")
        hit = any(fnmatch.fnmatch("/".join(parts[:i]), p) for i in range(1, len(parts) + 1))
        if p.startswith("**/"):
            hit = hit or any(fnmatch.fnmatch(part, p[3:]) for part in parts)
        if hit:
            result = not neg
    return result


def check(src):
    dockerfile = os.path.join(src, "deploy", "Dockerfile")
    instrs = instructions(open(dockerfile).read())
    st = stages(instrs)
    ignore = dockerignore_patterns(os.path.join(src, "deploy", "Dockerfile.dockerignore"))

    names = [(s["name"], s["image"]) for s in st]
    if names != [("build", "debian:bookworm"), ("runtime", "debian:bookworm-slim")]:
        fail(f"stages {names}: expected build on debian:bookworm, runtime on debian:bookworm-slim")
    for s in st:
        if s["image"].endswith(":latest") or ":" not in s["image"]:
            fail(f"line {s['line']}: base image {s['image']} has no pinned tag")

    for no, kw, args in instrs:
        if kw == "ADD" and re.search(r"https?://", args):
            fail(f"line {no}: ADD of a URL: the build downloads only through apt")
        if kw == "RUN":
            if re.search(r"\b(curl|wget)\b", args):
                fail(f"line {no}: curl/wget in RUN: the build downloads only through apt")
            if re.search(r"apt-get\s+(\S+\s+)*install", args):
                if not re.search(r"\s-y\b|--yes|--assume-yes", args):
                    fail(f"line {no}: apt-get install without -y")
                if "--no-install-recommends" not in args:
                    fail(f"line {no}: apt-get install without --no-install-recommends")
            if "apt-get update" in args and "rm -rf /var/lib/apt/lists" not in args:
                fail(f"line {no}: apt-get update without rm -rf /var/lib/apt/lists/* in the same RUN")
        if kw == "COPY" and "--from=" not in args:
            try:
                words = shlex.split(args)
            except ValueError as e:
                fail(f"line {no}: COPY {args}: {e}")
                continue
            words = [w for w in words if not w.startswith("--")]
            for source in words[:-1]:
                if source == ".":
                    continue
                if not os.path.exists(os.path.join(src, source)):
                    fail(f"line {no}: COPY source {source} does not exist")
                elif ignored(source, ignore):
                    fail(f"line {no}: COPY source {source} is excluded by deploy/Dockerfile.dockerignore")

    # The build context must carry what the build needs, and not the host's build trees.
    for needed in ("CMakeLists.txt", "scripts/install-deps.sh", "scripts/build.sh", "core", "server", "client",
                   "proto", "optim", "deploy/healthcheck.sh", "deploy/runtime-packages.txt"):
        if not os.path.exists(os.path.join(src, needed)):
            fail(f"{needed} does not exist")
        elif ignored(needed, ignore):
            fail(f"{needed} is excluded by deploy/Dockerfile.dockerignore")
    for unwanted in ("build", "build-asan", "out", ".git"):
        if not ignored(unwanted, ignore):
            fail(f"{unwanted}/ is not excluded by deploy/Dockerfile.dockerignore")

    if len(st) != 2:
        return
    build, runtime = st
    build_runs = " ".join(a for _, k, a in build["instrs"] if k == "RUN")
    for script in ("scripts/install-deps.sh", "scripts/build.sh"):
        if not re.search(rf"\bbash {re.escape(script)}\b", build_runs):
            fail(f"the build stage does not run {script}")

    rt = {}
    for no, kw, args in runtime["instrs"]:
        rt.setdefault(kw, []).append((no, args))
    rt_runs = " ".join(a for _, a in rt.get("RUN", []))
    installs = re.findall(r"apt-get\s+install[^&;|]*", rt_runs)
    if not installs or any("runtime-packages.txt" not in i for i in installs):
        fail("the runtime stage must install its packages from deploy/runtime-packages.txt only")
    users = [a for _, a in rt.get("USER", [])]
    if not users or not re.fullmatch(r"65532(:65532)?", users[-1]):
        fail(f"runtime USER {users[-1] if users else None}: expected the numeric non-root 65532:65532")
    exposed = set(" ".join(a for _, a in rt.get("EXPOSE", [])).split())
    for port in ("50051", "9090", "8080"):
        if port not in exposed and f"{port}/tcp" not in exposed:
            fail(f"runtime does not EXPOSE {port}")
    env = " ".join(a for _, a in rt.get("ENV", []))
    for name, value in (("GEOTRAJ_ADDRESS", "0.0.0.0:50051"), ("GEOTRAJ_METRICS_ADDRESS", "0.0.0.0:9090"),
                        ("GEOTRAJ_WEB_ADDRESS", "127.0.0.1:8080"),
                        ("GEOTRAJ_LOG_FORMAT", "json")):
        if not re.search(rf"\b{name}={re.escape(value)}\b", env):
            fail(f"runtime ENV lacks {name}={value}")
    if [a for _, a in rt.get("STOPSIGNAL", [])] != ["SIGTERM"]:
        fail("runtime STOPSIGNAL is not SIGTERM")
    hc = [a for _, a in rt.get("HEALTHCHECK", [])]
    if len(hc) != 1 or "CMD" not in hc[0]:
        fail("runtime needs one HEALTHCHECK ... CMD")
    else:
        cmd = hc[0][hc[0].index("CMD") + 3:].strip()
        try:
            argv = json.loads(cmd)
        except json.JSONDecodeError:
            fail("HEALTHCHECK CMD is not in exec form (JSON array)")
            argv = []
        if argv and argv[0] == "/usr/local/bin/geotraj-healthcheck":
            script = open(os.path.join(src, "deploy", "healthcheck.sh")).read()
            if not re.search(r"/usr/local/bin/geotraj\b.*\bhealth\b", script.replace("\\\n", " ")):
                fail("deploy/healthcheck.sh does not run `geotraj ... health`")
            if not re.search(r"deploy/healthcheck\.sh\s+\S*/usr/local/bin/geotraj-healthcheck",
                             " ".join(a for _, k, a in build["instrs"] if k == "RUN")):
                fail("the build stage does not install deploy/healthcheck.sh as /usr/local/bin/geotraj-healthcheck")
        elif argv and not any("geotraj" in a and "health" in " ".join(argv) for a in argv):
            fail(f"HEALTHCHECK {argv} does not use the geotraj CLI's health command")
    ep = [a for _, a in rt.get("ENTRYPOINT", [])]
    try:
        if not ep or json.loads(ep[-1])[0] != "/usr/local/bin/geotrajd":
            fail("ENTRYPOINT must be [\"/usr/local/bin/geotrajd\"] in exec form")
    except (json.JSONDecodeError, IndexError):
        fail("ENTRYPOINT is not in exec form: a shell as PID 1 would not pass SIGTERM on")
    labels = " ".join(a for _, a in rt.get("LABEL", []))
    for key in ("title", "description", "version", "revision", "created"):
        if f"org.opencontainers.image.{key}=" not in labels:
            fail(f"runtime lacks the label org.opencontainers.image.{key}")
    copies_from = [a for _, a in rt.get("COPY", []) if "--from=build" in a]
    if not copies_from:
        fail("the runtime stage copies nothing from the build stage")
    if re.search(r"\b(build-essential|g\+\+|cmake|-dev)\b", rt_runs):
        fail("the runtime stage installs build tools or -dev packages")


def seconds(text):
    m = re.fullmatch(r"(?:(\d+)m)?(?:(\d+)s)?", str(text))
    return int(m.group(1) or 0) * 60 + int(m.group(2) or 0) if m else None


def check_compose(src):
    """deploy/compose.yaml and compose.tls.yaml: what `docker compose config` cannot tell."""
    try:
        import yaml
    except ImportError:
        print("python3-yaml not installed: compose files not checked")
        return
    deploy = os.path.join(src, "deploy")
    base = yaml.safe_load(open(os.path.join(deploy, "compose.yaml")))
    svc = base["services"]["geotrajd"]
    build = svc.get("build", {})
    context = os.path.normpath(os.path.join(deploy, build.get("context", ".")))
    if not os.path.exists(os.path.join(context, build.get("dockerfile", "Dockerfile"))):
        fail(f"compose.yaml: build dockerfile {build.get('dockerfile')} not found from context {context}")
    if svc.get("read_only") is not True:
        fail("compose.yaml: geotrajd is not read_only")
    if str(svc.get("user")) != "65532:65532":
        fail(f"compose.yaml: user {svc.get('user')}, expected 65532:65532")
    if "ALL" not in svc.get("cap_drop", []):
        fail("compose.yaml: cap_drop lacks ALL")
    env = svc.get("environment", {})
    drain = int(env.get("GEOTRAJ_DRAIN_SECONDS", 30))
    grace = seconds(svc.get("stop_grace_period", "10s"))
    if grace is None or grace <= drain:
        fail(f"compose.yaml: stop_grace_period {svc.get('stop_grace_period')} is not above the drain ({drain} s)")
    test = svc.get("healthcheck", {}).get("test", [])
    if test[:2] != ["CMD", "/usr/local/bin/geotraj-healthcheck"]:
        fail(f"compose.yaml: healthcheck {test} is not the image's geotraj-healthcheck")
    for name, service in base["services"].items():
        for vol in service.get("volumes", []):
            host = vol.split(":")[0]
            if host.startswith(".") and not os.path.exists(os.path.join(deploy, host)):
                fail(f"compose.yaml: {name} mounts {host}, which does not exist")
        for port in service.get("ports", []):
            if not str(port).startswith("127.0.0.1:"):
                fail(f"compose.yaml: {name} publishes {port} beyond loopback")
    tls = yaml.safe_load(open(os.path.join(deploy, "compose.tls.yaml")))
    tsvc = tls["services"]["geotrajd"]
    defined = tls.get("secrets", {})
    for name in tsvc.get("secrets", []):
        if name not in defined:
            fail(f"compose.tls.yaml: secret {name} is used but not defined")
    for var, value in tsvc.get("environment", {}).items():
        if str(value).startswith("/run/secrets/") and value.rsplit("/", 1)[1] not in tsvc.get("secrets", []):
            fail(f"compose.tls.yaml: {var}={value} names a secret the service does not mount")
    if str(tsvc.get("environment", {}).get("GEOTRAJ_PLAINTEXT")).lower() != "false":
        fail("compose.tls.yaml: GEOTRAJ_PLAINTEXT is not false")


# dockerfilelint 1.8.0's known false positives: (title, instruction) pairs.
DOCKERFILELINT_FALSE_POSITIVES = {("Invalid Argument Format", "HEALTHCHECK")}


def run_dockerfilelint(src, exe):
    path = os.path.join(src, "deploy", "Dockerfile")
    proc = subprocess.run([exe, "-j", path], capture_output=True, text=True)
    try:
        report = json.loads(proc.stdout)
    except json.JSONDecodeError:
        fail(f"dockerfilelint printed no JSON (exit {proc.returncode}): {proc.stdout[:400]} {proc.stderr[:400]}")
        return
    kept = 0
    for f in report.get("files", []):
        for issue in f.get("issues", []):
            keyword = issue.get("content", "").split(" ", 1)[0].upper()
            if (issue.get("title"), keyword) in DOCKERFILELINT_FALSE_POSITIVES:
                print(f"dockerfilelint (known false positive, ignored): line {issue['line']}: {issue['title']}")
                continue
            kept += 1
            fail(f"dockerfilelint: line {issue['line']}: {issue['title']}: {issue['description']}")
    print(f"dockerfilelint: {kept} issue(s)")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("src")
    parser.add_argument("--dockerfilelint", default=None)
    args = parser.parse_args()
    check(args.src)
    check_compose(args.src)
    exe = args.dockerfilelint or shutil.which("dockerfilelint")
    if exe:
        run_dockerfilelint(args.src, exe)
    else:
        print("dockerfilelint not found (npm install -g dockerfilelint@1.8.0): own rules only")
    if FAILURES:
        print(f"{len(FAILURES)} failure(s)", file=sys.stderr)
        return 1
    print("dockerfile_check: OK")
    return 0


if __name__ == "__main__":
    sys.exit(main())
