#!/usr/bin/env python3
"""Scaling out on one machine: three geotrajd behind a load balancer, calls spread and kept.

Three geotrajd on 127.0.0.1 ports the kernel chooses (port 0, read back from their logs), each serving one extra robot model named after
it (lb-backend-0/1/2, a renamed copy of the built-in ur5), so that a ListRobots answer says
which backend served the call. Then, per --mode:

  client  gRPC client-side load balancing, as a headless Kubernetes Service gives it: target
          ipv4:127.0.0.1:P0,127.0.0.1:P1,127.0.0.1:P2, policy round_robin, client-side health
          checking of geotraj.readiness, retry of UNAVAILABLE.
          300 ListRobots spread over all three; 300 PlanTrajectory (8 at a time) all OK, and
          each backend's geotraj_rpc_calls_total{method="PlanTrajectory",code="OK"} grew and
          they add up to 300. Backend 0 gets SIGTERM in the middle of 300 more calls: all OK
          (it drains; its refusals are UNAVAILABLE, which the client retries elsewhere).
          Backend 1 gets SIGKILL in the middle of 300 more: only calls in flight on it may
          fail, with UNAVAILABLE; every later call is OK, served by backend 2.
  nginx   nginx (grpc_pass, deploy/nginx/geotraj.conf with the upstream servers and listen
          port replaced) on an ephemeral port, its pid, logs and temp files in --work:
          300 ListRobots spread over all three, 300 PlanTrajectory all OK (per-backend
          metrics as above), a StreamSamples (path C, 10 s at 100 Hz: 1001
          samples) through the proxy; then SIGKILL of backend 0 in the middle of 300 calls:
          only calls in flight may fail (UNAVAILABLE), later ones all OK.
          Exit 77 (skipped) when nginx is not installed.

usage: lb_test.py --mode client|nginx --server GEOTRAJD --stubs PYSTUBS_DIR
                  --source SOURCE_DIR --work DIR [--nginx NGINX]
"""
import argparse
import concurrent.futures
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.request

SKIP = 77
CALLS = 300
WORKERS = 8
FAILURES = []
DETAILS = {}  # a failed call's details, per status code name, for the log


def fail(msg):
    FAILURES.append(msg)
    print(f"FAIL: {msg}", file=sys.stderr, flush=True)


def log(msg):
    print(msg, flush=True)


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def health_check(channel, service, timeout=5.0):
    """grpc.health.v1.Health/Check without generated stubs: the request is field 1 (string),
    the answer field 1 (enum; 1 = SERVING). Returns the status number, or the gRPC code name."""
    name = service.encode()
    request = (b"\x0a" + bytes([len(name)]) + name) if name else b""
    call = channel.unary_unary("/grpc.health.v1.Health/Check",
                               request_serializer=lambda b: b, response_deserializer=lambda b: b)
    try:
        answer = call(request, timeout=timeout)
    except grpc.RpcError as e:
        return e.code().name
    return answer[1] if len(answer) >= 2 and answer[0] == 0x08 else 0


def started_geotrajd(argv, env, log_path, timeout=60):
    """Runs geotrajd with its ports chosen by the kernel (port 0: no other process can take
    them between a probe and the bind) and reads the bound ports from its first lines:
    returns (process, log file, gRPC port, metrics port or None)."""
    log_file = open(log_path, "w")
    proc = subprocess.Popen(argv, env=env, stdout=log_file, stderr=subprocess.STDOUT)
    deadline = time.monotonic() + timeout
    while True:
        text = open(log_path).read()
        grpc_port = re.search(r"serving geotraj\.v1\.TrajectoryService on [^\s]*:(\d+)", text)
        metrics_port = re.search(r"metrics on http port (\d+)", text)
        wants_metrics = "--metrics-address" in argv
        if grpc_port and (metrics_port or not wants_metrics):
            return proc, log_file, int(grpc_port.group(1)), int(metrics_port.group(1)) if metrics_port else None
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            proc.wait()
            log_file.close()
            raise RuntimeError(f"geotrajd did not start (exit {proc.returncode}):\n{text[-2000:]}")
        time.sleep(0.05)


class Backend:
    def __init__(self, index, args, model_file):
        self.index = index
        self.name = f"lb-backend-{index}"
        env = dict(os.environ)
        env.update({
            "GEOTRAJ_ADDRESS": "127.0.0.1:0",
            "GEOTRAJ_PLAINTEXT": "true",
            # A short drain keeps the test short; calls here last milliseconds.
            "GEOTRAJ_DRAIN_SECONDS": "5",
        })
        argv = [args.server, "--robot-model", model_file, "--metrics-address", "127.0.0.1:0"]
        self.log_path = os.path.join(args.work, f"{self.name}.log")
        self.proc, self.log_file, self.port, self.metrics_port = started_geotrajd(argv, env, self.log_path)

    @property
    def address(self):
        return f"127.0.0.1:{self.port}"

    def wait_serving(self):
        channel = grpc.insecure_channel(self.address)
        try:
            grpc.channel_ready_future(channel).result(timeout=60)
            for service in ("", "geotraj.readiness"):
                # readiness turns SERVING once the warm-up plan has run
                deadline = time.monotonic() + 60
                while (status := health_check(channel, service)) != 1 and time.monotonic() < deadline:
                    time.sleep(0.1)
                if status != 1:
                    raise RuntimeError(f"{self.name}: health {service!r} is {status}, expected SERVING")
        finally:
            channel.close()

    def calls_ok(self, method):
        """geotraj_rpc_calls_total{method=METHOD, code="OK"} from this backend's /metrics."""
        with urllib.request.urlopen(f"http://127.0.0.1:{self.metrics_port}/metrics", timeout=10) as r:
            text = r.read().decode()
        total = 0.0
        for labels, value in re.findall(r"^geotraj_rpc_calls_total\{([^}]*)\}\s+(\S+)", text, re.M):
            lab = dict(re.findall(r'(\w+)="([^"]*)"', labels))
            if lab.get("method", "").split("/")[-1] == method and lab.get("code") == "OK":
                total += float(value)
        return total

    def stop(self, sig=signal.SIGTERM):
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.log_file.close()


def robot_model_files(args):
    """lb-backend-0/1/2: the built-in ur5 under three names, as --robot-model files, taken
    from the ListRobots answer of a throw-away geotrajd."""
    env = dict(os.environ, GEOTRAJ_ADDRESS="127.0.0.1:0")
    probe, probe_log, port, _ = started_geotrajd([args.server], env, os.path.join(args.work, "probe.log"))
    try:
        with grpc.insecure_channel(f"127.0.0.1:{port}") as channel:
            grpc.channel_ready_future(channel).result(timeout=60)
            robots = rpc.TrajectoryServiceStub(channel).ListRobots(pb.ListRobotsRequest(), timeout=30).robots
    finally:
        probe.kill()
        probe.wait()
        probe_log.close()
    ur5 = next(m for m in robots if m.name == "ur5")
    files = []
    for i in range(3):
        model = pb.RobotModel()
        model.CopyFrom(ur5)
        model.name = f"lb-backend-{i}"
        path = os.path.join(args.work, f"lb-backend-{i}.json")
        with open(path, "w") as f:
            f.write(json_format.MessageToJson(model))
        files.append(path)
    return files


def served_by(stub):
    names = [r.name for r in stub.ListRobots(pb.ListRobotsRequest(), timeout=10).robots]
    mine = [n for n in names if n.startswith("lb-backend-")]
    if len(mine) != 1:
        raise AssertionError(f"ListRobots answered {names}: expected one lb-backend-N")
    return mine[0]


def spread(stub, backends, label):
    counts = {b.name: 0 for b in backends}
    for _ in range(CALLS):
        counts[served_by(stub)] += 1
    log(f"{label}: {CALLS} ListRobots calls per backend: {counts}")
    for name, n in counts.items():
        # Round robin gives 100 each; a tenth of that still shows every backend in use.
        if n < CALLS // 30:
            fail(f"{label}: {name} served {n} of {CALLS} calls")
    return counts


def plan_request(source, which):
    req = pb.PlanRequest()
    with open(os.path.join(source, "client", "grpcurl", f"plan_demo_path_{which}.json")) as f:
        json_format.Parse(f.read(), req)
    return req


def run_calls(stub, req, count, during=None, at=None):
    """`count` PlanTrajectory calls, WORKERS at a time; `during()` runs once `at` calls have
    been submitted (they may still be in flight). Returns [(index, code name)] in order of
    completion."""
    results = []
    with concurrent.futures.ThreadPoolExecutor(WORKERS) as pool:
        futures = {}
        for i in range(count):
            if during is not None and i == at:
                during()
            futures[pool.submit(stub.PlanTrajectory, req, timeout=60)] = i
            # Keep at most 2 * WORKERS queued, so that `at` means "in the middle of the run".
            while sum(1 for f in futures if not f.done()) > 2 * WORKERS:
                time.sleep(0.001)
        for f in concurrent.futures.as_completed(futures):
            try:
                resp = f.result()
                if resp.closed_loop.max_error > 1e-9:
                    fail(f"call {futures[f]}: closed-loop error {resp.closed_loop.max_error}")
                results.append((futures[f], "OK"))
            except grpc.RpcError as e:
                results.append((futures[f], e.code().name))
                DETAILS.setdefault(e.code().name, e.details())
    return sorted(results)


def check_all_ok(results, label):
    bad = [(i, c) for i, c in results if c != "OK"]
    log(f"{label}: {len(results) - len(bad)} of {len(results)} OK")
    if bad:
        fail(f"{label}: {len(bad)} calls failed: {bad[:10]}")


def check_metrics(backends, before, label):
    after = {b.name: b.calls_ok("PlanTrajectory") for b in backends}
    delta = {n: after[n] - before[n] for n in after}
    log(f"{label}: geotraj_rpc_calls_total{{method=PlanTrajectory,code=OK}} grew by {delta}")
    for name, d in delta.items():
        if d < 1:
            fail(f"{label}: {name} served no PlanTrajectory call")
    if sum(delta.values()) != CALLS:
        fail(f"{label}: the backends counted {sum(delta.values())} OK calls, expected {CALLS}")


def check_kill_results(results, killed_at, label):
    """After SIGKILL of one backend: only UNAVAILABLE, only for calls already submitted
    when it died or just after (in flight on its connection), and all later calls OK."""
    bad = [(i, c) for i, c in results if c != "OK"]
    log(f"{label}: {len(results) - len(bad)} of {len(results)} OK; failed: {bad}"
        + "".join(f"; {c}: {DETAILS.get(c)!r}" for c in sorted({c for _, c in bad})))
    for i, code in bad:
        if code != "UNAVAILABLE":
            fail(f"{label}: call {i} failed with {code}, expected only UNAVAILABLE for calls in flight")
        if i >= killed_at + 3 * WORKERS:
            fail(f"{label}: call {i}, long after the kill (call {killed_at}), failed")
    if len(bad) > 2 * WORKERS:
        fail(f"{label}: {len(bad)} calls failed, more than could have been in flight")


# The client configuration docs/deploy.md recommends: round robin over every address the
# name resolves to, client-side health checking (a draining pod leaves the rotation when
# its readiness turns NOT_SERVING), and a retry of UNAVAILABLE (every geotraj call is a
# pure function of its request, so a call refused by a draining pod may go to another).
SERVICE_CONFIG = json.dumps({
    "loadBalancingConfig": [{"round_robin": {}}],
    "healthCheckConfig": {"serviceName": "geotraj.readiness"},
    "methodConfig": [{
        "name": [{"service": "geotraj.v1.TrajectoryService"}],
        "retryPolicy": {"maxAttempts": 3, "initialBackoff": "0.05s", "maxBackoff": "1s",
                        "backoffMultiplier": 2, "retryableStatusCodes": ["UNAVAILABLE"]},
    }],
})


def check_drain_results(results, label):
    """Across a SIGTERM: all OK, the contract of --drain-seconds and --lame-duck-seconds with
    the client above. Calls in flight finish; calls that reach the draining backend get
    UNAVAILABLE (trailers only), which the client retries on another backend."""
    bad = [(i, c) for i, c in results if c != "OK"]
    log(f"{label}: {len(results) - len(bad)} of {len(results)} OK"
        + "".join(f"; {c}: {DETAILS.get(c)!r}" for c in sorted({c for _, c in bad})))
    if bad:
        fail(f"{label}: {len(bad)} calls failed: {bad[:10]}")


def client_mode(args, backends, req):
    target = "ipv4:" + ",".join(b.address for b in backends)
    log(f"client-side round_robin over {target}")
    channel = grpc.insecure_channel(target, options=[
        ("grpc.service_config", SERVICE_CONFIG),
        ("grpc.enable_retries", 1),
    ])
    grpc.channel_ready_future(channel).result(timeout=60)
    stub = rpc.TrajectoryServiceStub(channel)
    # Until every subchannel is READY, round robin spreads over fewer backends.
    seen = set()
    for _ in range(100):
        seen.add(served_by(stub))
        if len(seen) == len(backends):
            break
    spread(stub, backends, "round_robin")

    before = {b.name: b.calls_ok("PlanTrajectory") for b in backends}
    check_all_ok(run_calls(stub, req, CALLS), "round_robin PlanTrajectory")
    check_metrics(backends, before, "round_robin")

    # Graceful: SIGTERM to backend 0 in the middle of a run. It drains (readiness
    # NOT_SERVING, GOAWAY) and the client moves its calls to the other two.
    def term():
        log("SIGTERM to lb-backend-0")
        backends[0].proc.send_signal(signal.SIGTERM)
    check_drain_results(run_calls(stub, req, CALLS, during=term, at=CALLS // 3), "round_robin across a SIGTERM")
    backends[0].stop()
    names = {served_by(stub) for _ in range(20)}
    if names != {"lb-backend-1", "lb-backend-2"}:
        fail(f"after lb-backend-0 stopped, calls went to {names}")

    # Abrupt: SIGKILL to backend 1 in the middle of a run.
    def kill():
        log("SIGKILL to lb-backend-1")
        backends[1].proc.kill()
        backends[1].proc.wait()  # dead before the next call is submitted
    check_kill_results(run_calls(stub, req, CALLS, during=kill, at=CALLS // 3), CALLS // 3, "round_robin across a SIGKILL")
    backends[1].stop()
    check_all_ok(run_calls(stub, req, 50), "round_robin on the last backend")
    names = {served_by(stub) for _ in range(20)}
    if names != {"lb-backend-2"}:
        fail(f"with only lb-backend-2 left, calls went to {names}")
    channel.close()


NGINX_MAIN = """\
# Generated by tests/deploy/lb_test.py: a throw-away nginx with every path under {work}.
daemon off;
master_process off;
worker_processes 1;
pid {work}/nginx.pid;
error_log {work}/nginx-error.log info;
events {{ worker_connections 1024; }}
http {{
    access_log {work}/nginx-access.log;
    client_body_temp_path {work}/nginx-tmp/body;
    proxy_temp_path {work}/nginx-tmp/proxy;
    fastcgi_temp_path {work}/nginx-tmp/fastcgi;
    uwsgi_temp_path {work}/nginx-tmp/uwsgi;
    scgi_temp_path {work}/nginx-tmp/scgi;
    include {work}/geotraj.conf;
}}
"""


def nginx_conf(args, backends, port):
    """deploy/nginx/geotraj.conf with our backends and listen port."""
    text = open(os.path.join(args.source, "deploy", "nginx", "geotraj.conf")).read()
    servers = re.findall(r"^(\s*)server\s+[^\s;{]+:\d+([^;]*);", text, re.M)
    if not servers:
        raise SystemExit("deploy/nginx/geotraj.conf: no 'server HOST:PORT ...;' line in an upstream block")
    indent, params = servers[0]
    replacement = "".join(f"{indent}server {b.address}{params};\n" for b in backends)
    text, n = re.subn(r"^\s*server\s+[^\s;{]+:\d+[^;]*;\n", "", text, flags=re.M)
    text = re.sub(r"(upstream\s+\S+\s*\{\n)", lambda m: m.group(1) + replacement, text, count=1)
    text, n = re.subn(r"^(\s*)listen\s+\d+(\s+http2)?\s*;", rf"\g<1>listen 127.0.0.1:{port} http2;", text, flags=re.M)
    if n != 1:
        raise SystemExit(f"deploy/nginx/geotraj.conf: expected one 'listen PORT http2;', found {n}")
    return text


def started_nginx(args, backends):
    """nginx on a free port: nginx cannot listen on port 0 and say which it got, so a port
    another process took between the probe and nginx's bind is met by trying another.
    Returns (process, port)."""
    os.makedirs(os.path.join(args.work, "nginx-tmp"), exist_ok=True)
    main_conf = os.path.join(args.work, "nginx.conf")
    with open(main_conf, "w") as f:
        f.write(NGINX_MAIN.format(work=args.work))
    error_log = os.path.join(args.work, "nginx-error.log")
    base = [args.nginx, "-p", args.work, "-c", main_conf, "-e", error_log]
    for attempt in range(5):
        port = free_port()
        with open(os.path.join(args.work, "geotraj.conf"), "w") as f:
            f.write(nginx_conf(args, backends, port))
        test = subprocess.run(base + ["-t"], capture_output=True, text=True)
        if test.returncode != 0:
            raise SystemExit(f"nginx -t rejected the configuration:\n{test.stderr}")
        proc = subprocess.Popen(base, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + 30
        while proc.poll() is None and time.monotonic() < deadline:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                return proc, port
            except OSError:
                time.sleep(0.05)
        proc.kill()
        proc.wait()
        tail = "".join(open(error_log).readlines()[-3:]) if os.path.exists(error_log) else ""
        log(f"nginx did not listen on port {port} (attempt {attempt + 1}): {tail}")
    raise RuntimeError("nginx did not start in 5 attempts; see nginx-error.log")


def nginx_mode(args, backends, req):
    proc, port = started_nginx(args, backends)
    try:
        channel = grpc.insecure_channel(f"127.0.0.1:{port}")
        grpc.channel_ready_future(channel).result(timeout=60)
        stub = rpc.TrajectoryServiceStub(channel)
        spread(stub, backends, "nginx")

        before = {b.name: b.calls_ok("PlanTrajectory") for b in backends}
        check_all_ok(run_calls(stub, req, CALLS), "nginx PlanTrajectory")
        check_metrics(backends, before, "nginx")

        stream_req = plan_request(args.source, "c")
        samples = [s for batch in stub.StreamSamples(stream_req, timeout=120) for s in batch.samples]
        log(f"nginx StreamSamples: {len(samples)} samples, last t = {samples[-1].t if samples else None}")
        if len(samples) != 1001 or abs(samples[-1].t - 10.0) > 1e-12:
            fail(f"StreamSamples through nginx: {len(samples)} samples, expected 1001 ending at t = 10 s")

        def kill():
            log("SIGKILL to lb-backend-0")
            backends[0].proc.kill()
            backends[0].proc.wait()  # dead before the next call is submitted
        check_kill_results(run_calls(stub, req, CALLS, during=kill, at=CALLS // 3), CALLS // 3, "nginx across a SIGKILL")
        backends[0].stop()
        check_all_ok(run_calls(stub, req, 50), "nginx on two backends")
        names = {served_by(stub) for _ in range(20)}
        if names != {"lb-backend-1", "lb-backend-2"}:
            fail(f"after lb-backend-0 died, nginx sent calls to {names}")
        channel.close()
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    if FAILURES:
        err = os.path.join(args.work, "nginx-error.log")
        if os.path.exists(err):
            log("--- nginx-error.log (last lines)\n" + "".join(open(err).readlines()[-20:]))


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--mode", choices=["client", "nginx"], required=True)
    parser.add_argument("--server", required=True)
    parser.add_argument("--stubs", required=True)
    parser.add_argument("--source", required=True)
    parser.add_argument("--work", required=True)
    parser.add_argument("--nginx", default=None)
    args = parser.parse_args()

    if args.mode == "nginx":
        args.nginx = args.nginx or shutil.which("nginx") or ("/usr/sbin/nginx" if os.path.exists("/usr/sbin/nginx") else None)
        if not args.nginx:
            log("SKIP: nginx is not installed (apt-get install nginx)")
            return SKIP

    sys.path.insert(0, args.stubs)
    global grpc, json_format, pb, rpc
    import grpc
    from google.protobuf import json_format
    from geotraj.v1 import geotraj_pb2 as pb
    from geotraj.v1 import geotraj_pb2_grpc as rpc

    args.work = os.path.abspath(args.work)
    shutil.rmtree(args.work, ignore_errors=True)
    os.makedirs(args.work)
    models = robot_model_files(args)
    backends = [Backend(i, args, models[i]) for i in range(3)]
    try:
        for b in backends:
            b.wait_serving()
        log("backends: " + ", ".join(f"{b.name} on {b.address}" for b in backends))
        req = plan_request(args.source, "a")
        if args.mode == "client":
            client_mode(args, backends, req)
        else:
            nginx_mode(args, backends, req)
    finally:
        for b in backends:
            b.stop(signal.SIGKILL)
    if FAILURES:
        for b in backends:
            log(f"--- {b.log_path} (last lines)\n" + "".join(open(b.log_path).readlines()[-10:]))
        log(f"{len(FAILURES)} failure(s)")
        return 1
    log(f"lb_test --mode {args.mode}: OK")
    return 0


if __name__ == "__main__":
    sys.exit(main())
