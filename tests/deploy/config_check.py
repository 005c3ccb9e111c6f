#!/usr/bin/env python3
"""The deployment files' geotrajd configuration against the geotrajd that was built.

1. Every GEOTRAJ_* variable that deploy/ sets for geotrajd (Dockerfile ENV, compose files,
   deploy/k8s/geotraj.env, the Deployment's env, the TLS overlay's literals) is one that
   `geotrajd --help` names: a misspelt variable would be ignored silently.
2. geotrajd starts with deploy/k8s/geotraj.env as its environment (the addresses moved to
   free loopback ports on the command line, which wins, and a tokens file), reports
   SERVING on its health-only port for "" and geotraj.readiness, answers its web side's
   GET /v1/robots with the token only, and exits 0 on SIGTERM.

usage: config_check.py SOURCE_DIR GEOTRAJD
"""
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile

import yaml  # python3-yaml

# Variables that deploy/ sets for other programs than geotrajd.
NOT_GEOTRAJD = {"GEOTRAJ_HEALTHCHECK_SERVICE", "GEOTRAJ_HEALTHCHECK_CLI"}


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def env_file(path):
    pairs = {}
    for line in open(path):
        line = line.strip()
        if line and not line.startswith("#"):
            key, _, value = line.partition("=")
            pairs[key] = value
    return pairs


def configured_names(src):
    d = os.path.join(src, "deploy")
    names = {}
    dockerfile = "".join(l for l in open(os.path.join(d, "Dockerfile")) if not l.lstrip().startswith("#"))
    for instruction in dockerfile.replace("\\\n", " ").splitlines():
        if instruction.startswith("ENV "):
            for m in re.finditer(r"\b(GEOTRAJ_[A-Z0-9_]+)=", instruction):
                names.setdefault(m.group(1), "deploy/Dockerfile ENV")
    for f in ("compose.yaml", "compose.tls.yaml"):
        doc = yaml.safe_load(open(os.path.join(d, f)))
        for key in doc["services"]["geotrajd"].get("environment", {}):
            names.setdefault(key, f"deploy/{f}")
    for key in env_file(os.path.join(d, "k8s", "geotraj.env")):
        names.setdefault(key, "deploy/k8s/geotraj.env")
    for doc in yaml.safe_load_all(open(os.path.join(d, "k8s", "deployment.yaml"))):
        for c in doc["spec"]["template"]["spec"]["containers"]:
            for e in c.get("env", []):
                names.setdefault(e["name"], "deploy/k8s/deployment.yaml")
    overlay = yaml.safe_load(open(os.path.join(d, "k8s-tls", "kustomization.yaml")))
    for gen in overlay.get("configMapGenerator", []):
        for lit in gen.get("literals", []):
            names.setdefault(lit.partition("=")[0], "deploy/k8s-tls/kustomization.yaml")
    return {k: v for k, v in names.items() if k.startswith("GEOTRAJ_") and k not in NOT_GEOTRAJD}


def health(port, service):
    import grpc  # python3-grpcio
    name = service.encode()
    request = (b"\x0a" + bytes([len(name)]) + name) if name else b""
    with grpc.insecure_channel(f"127.0.0.1:{port}") as channel:
        grpc.channel_ready_future(channel).result(timeout=30)
        call = channel.unary_unary("/grpc.health.v1.Health/Check",
                                   request_serializer=lambda b: b, response_deserializer=lambda b: b)
        answer = call(request, timeout=10)
    return answer[1] if len(answer) >= 2 and answer[0] == 0x08 else 0


def main():
    src, server = sys.argv[1], sys.argv[2]
    help_text = subprocess.run([server, "--help"], capture_output=True, text=True).stdout
    known = set(re.findall(r"\bGEOTRAJ_[A-Z0-9_]+", help_text))
    failures = []
    names = configured_names(src)
    for name, where in sorted(names.items()):
        if name not in known:
            failures.append(f"{where} sets {name}, which `geotrajd --help` does not name")
    if not failures:
        print(f"{len(names)} variables set in deploy/, all named by geotrajd --help")

    env = dict(os.environ)
    env.update(env_file(os.path.join(src, "deploy", "k8s", "geotraj.env")))
    grpc_port, health_port, metrics_port, web_port = free_port(), free_port(), free_port(), free_port()
    with tempfile.TemporaryDirectory() as tmp:
        tokens = os.path.join(tmp, "tokens")
        with open(tokens, "w") as f:
            f.write("config-check-token-0123456789 plan,stream\n")
        env["GEOTRAJ_AUTH_TOKENS_FILE"] = tokens
        argv = [server, "--address", f"127.0.0.1:{grpc_port}", "--health-address", f"127.0.0.1:{health_port}",
                "--metrics-address", f"127.0.0.1:{metrics_port}", "--web-address", f"127.0.0.1:{web_port}"]
        proc = subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        try:
            for service in ("", "geotraj.readiness"):
                status = health(health_port, service)
                if status != 1:
                    failures.append(f"with deploy/k8s/geotraj.env, health {service!r} is {status}, not SERVING")
            # The web side with the tokens: none is 401, the token's is 200.
            import urllib.error
            import urllib.request
            url = f"http://127.0.0.1:{web_port}/v1/robots"
            try:
                urllib.request.urlopen(url, timeout=10)
                failures.append("GET /v1/robots without a token was answered")
            except urllib.error.HTTPError as e:
                if e.code != 401:
                    failures.append(f"GET /v1/robots without a token: {e.code}, not 401")
            authorized = urllib.request.Request(url, headers={"Authorization": "Bearer config-check-token-0123456789"})
            with urllib.request.urlopen(authorized, timeout=10) as answer:
                if answer.status != 200 or b'"robots"' not in answer.read():
                    failures.append("GET /v1/robots with the token did not list the robots")
            proc.send_signal(signal.SIGTERM)
            code = proc.wait(timeout=60)
            if code != 0:
                failures.append(f"geotrajd exited {code} after SIGTERM")
        except Exception as e:  # the process log says more than the exception
            failures.append(f"geotrajd with deploy/k8s/geotraj.env: {e}")
        finally:
            if proc.poll() is None:
                proc.kill()
            out = proc.communicate()[0]
    if failures:
        print(out)
        for f in failures:
            print(f"FAIL: {f}", file=sys.stderr)
        return 1
    print("geotrajd served with deploy/k8s/geotraj.env and stopped cleanly on SIGTERM")
    print("config_check: OK")
    return 0


if __name__ == "__main__":
    sys.exit(main())
