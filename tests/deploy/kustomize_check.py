#!/usr/bin/env python3
"""Renders deploy/k8s and checks that the objects fit together, without a cluster.

Rendering: with --kustomize EXE, `EXE build DIR` (EXE a kustomize binary, or kubectl for
`kubectl kustomize DIR`); without it, a small renderer here that does what kustomize does
for the fields deploy/k8s uses (resources, namespace, labels without selectors,
configMapGenerator from env files and literals with a content-hash name suffix, images) and
refuses any other field. With both, --compare checks that the two renderings agree, up to
the hash suffix (kustomize's own hash is not reimplemented here).

Checks on the rendered objects:
- apiVersion per kind (apps/v1 Deployment, autoscaling/v2 HPA, policy/v1 PDB, v1 ...);
  every namespaced object in one namespace, the Namespace object's;
- the Deployment's selector matches its pod labels; Services, the PDB and the topology
  spread select those pods; Service targetPorts name container ports;
- the headless Service (clusterIP None) serves the grpc port;
- gRPC probes (startup, liveness service "", readiness service geotraj.readiness) on the
  container port of GEOTRAJ_HEALTH_ADDRESS; GEOTRAJ_ADDRESS and GEOTRAJ_METRICS_ADDRESS
  ports are container ports; the Prometheus annotations name the metrics port;
- terminationGracePeriodSeconds > preStop sleep + GEOTRAJ_DRAIN_SECONDS (from the ConfigMap);
- non-root, read-only root, no privilege escalation, capabilities drop ALL, seccomp
  RuntimeDefault, requests and limits, no service-link variables;
- envFrom names a rendered ConfigMap; GEOTRAJ_AUTH_TOKENS_FILE lies in the mount of the
  Secret volume, whose Secret and key the example Secret (secret.example.yaml) defines;
- the HPA and the PDB target the Deployment, with minAvailable below the replicas;
- with TLS configured (deploy/k8s-tls), certificate and key lie in a mounted Secret volume
  and plaintext is off.

usage: kustomize_check.py [--kustomize EXE] [--compare] [--expect-tls] DIR
"""
import argparse
import copy
import hashlib
import json
import os
import re
import shlex
import subprocess
import sys

try:
    import yaml
except ImportError:
    print("SKIP: python3-yaml is not installed (apt-get install python3-yaml)")
    sys.exit(77)

FAILURES = []


def fail(msg):
    FAILURES.append(msg)
    print(f"FAIL: {msg}", file=sys.stderr)


API_VERSIONS = {
    "Namespace": "v1", "ConfigMap": "v1", "Secret": "v1", "Service": "v1",
    "Deployment": "apps/v1", "HorizontalPodAutoscaler": "autoscaling/v2",
    "PodDisruptionBudget": "policy/v1",
}
CLUSTER_SCOPED = {"Namespace"}


# --- the small renderer ------------------------------------------------------------------

SUPPORTED_FIELDS = {"apiVersion", "kind", "namespace", "resources", "labels", "configMapGenerator", "images"}


def load_yaml_docs(path):
    with open(path) as f:
        return [d for d in yaml.safe_load_all(f) if d is not None]


def read_env_file(path):
    pairs = []
    for line in open(path):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        key, sep, value = line.partition("=")
        if not sep:
            raise ValueError(f"{path}: line without '=': {line}")
        pairs.append((key, value))
    return pairs


def render(directory):
    kfile = os.path.join(directory, "kustomization.yaml")
    k = yaml.safe_load(open(kfile))
    unknown = set(k) - SUPPORTED_FIELDS
    if unknown:
        raise SystemExit(f"{kfile}: fields {sorted(unknown)} are beyond this renderer; use --kustomize")
    if k.get("apiVersion") != "kustomize.config.k8s.io/v1beta1" or k.get("kind") != "Kustomization":
        fail(f"{kfile}: apiVersion/kind is not kustomize.config.k8s.io/v1beta1 Kustomization")
    objects = []
    for res in k.get("resources", []):
        path = os.path.join(directory, res)
        if not os.path.isfile(path):
            fail(f"{kfile}: resource {res} is not a file")
            continue
        try:
            objects.extend(load_yaml_docs(path))
        except yaml.YAMLError as e:
            fail(f"{path}: {e}")
    renames = {}
    for gen in k.get("configMapGenerator", []):
        if gen.get("behavior", "create") != "create":
            raise SystemExit(f"{kfile}: configMapGenerator behavior {gen['behavior']} is beyond this renderer")
        data = {}
        for env in gen.get("envs", []):
            data.update(read_env_file(os.path.join(directory, env)))
        for lit in gen.get("literals", []):
            key, _, value = lit.partition("=")
            data[key] = value
        content = json.dumps({"kind": "ConfigMap", "name": gen["name"], "data": data}, sort_keys=True)
        name = f"{gen['name']}-{hashlib.sha256(content.encode()).hexdigest()[:10]}"
        renames[gen["name"]] = name
        objects.append({"apiVersion": "v1", "kind": "ConfigMap", "metadata": {"name": name}, "data": data})
    for obj in objects:
        meta = obj.setdefault("metadata", {})
        if "namespace" in k and obj.get("kind") not in CLUSTER_SCOPED:
            meta["namespace"] = k["namespace"]
        for entry in k.get("labels", []):
            if entry.get("includeSelectors") or entry.get("includeTemplates"):
                raise SystemExit(f"{kfile}: labels with includeSelectors/includeTemplates are beyond this renderer")
            meta.setdefault("labels", {}).update(entry.get("pairs", {}))
        if obj.get("kind") == "Deployment":
            pod = obj["spec"]["template"]["spec"]
            for c in pod.get("containers", []) + pod.get("initContainers", []):
                for src in c.get("envFrom", []):
                    ref = src.get("configMapRef")
                    if ref and ref.get("name") in renames:
                        ref["name"] = renames[ref["name"]]
                for img in k.get("images", []):
                    name, _, tag = c["image"].partition(":")
                    if name == img["name"]:
                        c["image"] = f"{img.get('newName', name)}:{img.get('newTag', tag or 'latest')}"
            for vol in pod.get("volumes", []):
                cm = vol.get("configMap")
                if cm and cm.get("name") in renames:
                    cm["name"] = renames[cm["name"]]
    return objects


def kustomize_build(exe, directory):
    argv = [exe, "kustomize", directory] if os.path.basename(exe).startswith("kubectl") else [exe, "build", directory]
    proc = subprocess.run(argv, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"{shlex.join(argv)} failed:\n{proc.stderr}")
    return [d for d in yaml.safe_load_all(proc.stdout) if d is not None]


def normalised(objects):
    """Objects keyed by (kind, name) with generated-name hash suffixes replaced by HASH."""
    text = yaml.safe_dump_all(sorted(objects, key=lambda o: (o["kind"], o["metadata"]["name"])), sort_keys=True)
    return re.sub(r"(geotraj-config)-[a-z0-9]{10}\b", r"\1-HASH", text)


# --- checks --------------------------------------------------------------------------------

def port_of(address):
    m = re.fullmatch(r".*:(\d+)", address or "")
    return int(m.group(1)) if m else None


def selects(selector, labels):
    return bool(selector) and all(labels.get(k) == v for k, v in selector.items())


def check(objects, secret_example, expect_tls):
    by_kind = {}
    for obj in objects:
        kind = obj.get("kind")
        name = obj.get("metadata", {}).get("name")
        if kind not in API_VERSIONS:
            fail(f"{kind} {name}: a kind this check does not know")
        elif obj.get("apiVersion") != API_VERSIONS[kind]:
            fail(f"{kind} {name}: apiVersion {obj.get('apiVersion')}, expected {API_VERSIONS[kind]}")
        by_kind.setdefault(kind, []).append(obj)

    namespaces = {o["metadata"]["name"] for o in by_kind.get("Namespace", [])}
    used_ns = {o["metadata"].get("namespace") for o in objects if o.get("kind") not in CLUSTER_SCOPED}
    if len(used_ns) != 1 or None in used_ns:
        fail(f"namespaced objects in namespaces {used_ns}: expected one")
    elif namespaces and used_ns != namespaces:
        fail(f"objects in {used_ns}, but the Namespace object is {namespaces}")

    deployments = by_kind.get("Deployment", [])
    if len(deployments) != 1:
        fail(f"{len(deployments)} Deployments: expected 1")
        return
    dep = deployments[0]
    dname = dep["metadata"]["name"]
    spec = dep["spec"]
    pod_labels = spec["template"]["metadata"].get("labels", {})
    if not selects(spec["selector"].get("matchLabels"), pod_labels):
        fail(f"Deployment {dname}: selector {spec['selector']} does not match pod labels {pod_labels}")
    replicas = spec.get("replicas", 1)
    if replicas < 2:
        fail(f"Deployment {dname}: replicas {replicas}, expected at least 2")
    pod = spec["template"]["spec"]
    containers = pod.get("containers", [])
    if len(containers) != 1:
        fail(f"Deployment {dname}: {len(containers)} containers, expected 1")
        return
    c = containers[0]
    ports = {p["containerPort"]: p.get("name") for p in c.get("ports", [])}
    port_names = {p.get("name"): p["containerPort"] for p in c.get("ports", [])}

    # Configuration: the ConfigMap(s) behind envFrom, and the container's own env.
    config_maps = {o["metadata"]["name"]: o.get("data", {}) for o in by_kind.get("ConfigMap", [])}
    env = {}
    for src in c.get("envFrom", []):
        ref = src.get("configMapRef")
        if ref:
            if ref["name"] not in config_maps:
                fail(f"envFrom configMapRef {ref['name']} is not among the rendered ConfigMaps {sorted(config_maps)}")
            else:
                env.update(config_maps[ref["name"]])
    for e in c.get("env", []):
        if "value" in e:
            env[e["name"]] = e["value"]
    for var in ("GEOTRAJ_ADDRESS", "GEOTRAJ_HEALTH_ADDRESS", "GEOTRAJ_METRICS_ADDRESS", "GEOTRAJ_DRAIN_SECONDS"):
        if var not in env:
            fail(f"the container's environment lacks {var}")
    grpc_port, health_port, metrics_port = (port_of(env.get(v)) for v in
                                            ("GEOTRAJ_ADDRESS", "GEOTRAJ_HEALTH_ADDRESS", "GEOTRAJ_METRICS_ADDRESS"))
    for what, port, name in (("GEOTRAJ_ADDRESS", grpc_port, "grpc"), ("GEOTRAJ_HEALTH_ADDRESS", health_port, "health"),
                             ("GEOTRAJ_METRICS_ADDRESS", metrics_port, "metrics")):
        if port not in ports:
            fail(f"{what} port {port} is not a container port {sorted(ports)}")
        elif ports[port] != name:
            fail(f"container port {port} ({what}) is named {ports[port]}, expected {name}")
    for var in ("GEOTRAJ_ADDRESS", "GEOTRAJ_HEALTH_ADDRESS", "GEOTRAJ_METRICS_ADDRESS"):
        if env.get(var, "").startswith("127.") or env.get(var, "").startswith("localhost"):
            fail(f"{var}={env[var]} listens on loopback: unreachable from the kubelet and other pods")

    # Probes: native gRPC on the health port.
    expected_service = {"startupProbe": "", "livenessProbe": "", "readinessProbe": "geotraj.readiness"}
    for probe, service in expected_service.items():
        p = c.get(probe)
        if not p or "grpc" not in p:
            fail(f"{probe}: missing or not a gRPC probe")
            continue
        if p["grpc"].get("port") != health_port:
            fail(f"{probe}: port {p['grpc'].get('port')}, but the health port (GEOTRAJ_HEALTH_ADDRESS) is {health_port}")
        if p["grpc"].get("service", "") != service:
            fail(f"{probe}: service {p['grpc'].get('service', '')!r}, expected {service!r}")

    # Termination: the drain fits in the grace period.
    grace = pod.get("terminationGracePeriodSeconds", 30)
    try:
        drain = float(env.get("GEOTRAJ_DRAIN_SECONDS", "30"))
    except ValueError:
        fail(f"GEOTRAJ_DRAIN_SECONDS={env.get('GEOTRAJ_DRAIN_SECONDS')} is not a number")
        drain = 30.0
    pre_stop = 0.0
    cmd = c.get("lifecycle", {}).get("preStop", {}).get("exec", {}).get("command", [])
    if cmd and os.path.basename(cmd[0]) == "sleep":
        pre_stop = float(cmd[1])
    elif c.get("lifecycle", {}).get("preStop", {}).get("sleep"):
        pre_stop = float(c["lifecycle"]["preStop"]["sleep"]["seconds"])
    if not grace > pre_stop + drain:
        fail(f"terminationGracePeriodSeconds {grace} <= preStop {pre_stop} s + GEOTRAJ_DRAIN_SECONDS {drain} s")

    # Security.
    psc, csc = pod.get("securityContext", {}), c.get("securityContext", {})
    if not (csc.get("runAsNonRoot", psc.get("runAsNonRoot"))):
        fail("runAsNonRoot is not set")
    if csc.get("runAsUser", psc.get("runAsUser")) in (0, None):
        fail("runAsUser is root or unset (the image's USER is 65532)")
    if csc.get("readOnlyRootFilesystem") is not True:
        fail("readOnlyRootFilesystem is not true")
    if csc.get("allowPrivilegeEscalation") is not False:
        fail("allowPrivilegeEscalation is not false")
    if "ALL" not in csc.get("capabilities", {}).get("drop", []):
        fail("capabilities do not drop ALL")
    if csc.get("seccompProfile", psc.get("seccompProfile", {})).get("type") != "RuntimeDefault":
        fail("seccompProfile is not RuntimeDefault")
    if csc.get("privileged"):
        fail("the container is privileged")
    if pod.get("enableServiceLinks", True):
        fail("enableServiceLinks is not false: Service variables (GEOTRAJ_METRICS_PORT=...) would mix with GEOTRAJ_*")
    for kind in ("requests", "limits"):
        for res in ("cpu", "memory"):
            if res not in c.get("resources", {}).get(kind, {}):
                fail(f"resources.{kind}.{res} is not set")
    image = c.get("image", "")
    if ":" not in image or image.endswith(":latest"):
        fail(f"image {image!r} has no pinned tag")

    # Prometheus annotations.
    ann = spec["template"]["metadata"].get("annotations", {})
    if ann.get("prometheus.io/scrape") != "true":
        fail("pod annotation prometheus.io/scrape is not \"true\"")
    if str(ann.get("prometheus.io/port")) != str(metrics_port):
        fail(f"pod annotation prometheus.io/port {ann.get('prometheus.io/port')} is not the metrics port {metrics_port}")

    # Volumes and mounts: the tokens file and (with TLS) certificate and key.
    volumes = {v["name"]: v for v in pod.get("volumes", [])}
    mounts = {m["name"]: m for m in c.get("volumeMounts", [])}
    for name in mounts:
        if name not in volumes:
            fail(f"volumeMount {name} has no volume")
    for name, m in mounts.items():
        if not m.get("readOnly"):
            fail(f"volumeMount {name} is not readOnly")

    def secret_file(var):
        """The (secret name, key) behind the file that env var `var` names, or None."""
        path = env.get(var)
        if not path:
            return None
        for name, m in mounts.items():
            prefix = m["mountPath"].rstrip("/") + "/"
            if path.startswith(prefix) and "secret" in volumes.get(name, {}):
                sec = volumes[name]["secret"]
                rel = path[len(prefix):]
                items = sec.get("items")
                key = next((i["key"] for i in items if i["path"] == rel), None) if items else rel
                if key is None:
                    fail(f"{var}={path}: no item of Secret volume {name} has path {rel}")
                return sec["secretName"], key
        fail(f"{var}={path} lies in no mounted Secret volume")
        return None

    tokens = secret_file("GEOTRAJ_AUTH_TOKENS_FILE")
    if tokens is None and "GEOTRAJ_AUTH_TOKENS_FILE" not in env:
        fail("GEOTRAJ_AUTH_TOKENS_FILE is not set: the service would accept calls without a token")
    if tokens and secret_example:
        ex = [d for d in load_yaml_docs(secret_example) if d.get("kind") == "Secret"]
        if not ex or ex[0]["metadata"]["name"] != tokens[0]:
            fail(f"{secret_example} does not define the Secret {tokens[0]}")
        else:
            data = {**ex[0].get("data", {}), **ex[0].get("stringData", {})}
            if tokens[1] not in data:
                fail(f"{secret_example}: Secret {tokens[0]} has no key {tokens[1]}")
            else:
                for line in str(data[tokens[1]]).splitlines():
                    if line.strip() and not re.fullmatch(r"\S+(\s+(plan|stream)(,(plan|stream))*)?", line.strip()):
                        fail(f"{secret_example}: tokens line {line!r} is not 'TOKEN [SCOPE,...]'")
                if "PLACEHOLDER" not in str(data[tokens[1]]):
                    fail(f"{secret_example}: the example token is not marked PLACEHOLDER")
            if ex[0]["metadata"].get("namespace") not in used_ns:
                fail(f"{secret_example}: namespace {ex[0]['metadata'].get('namespace')} is not {used_ns}")
    tls = env.get("GEOTRAJ_TLS_CERT") or env.get("GEOTRAJ_TLS_KEY")
    if expect_tls and not tls:
        fail("TLS expected, but GEOTRAJ_TLS_CERT/GEOTRAJ_TLS_KEY are not set")
    if tls:
        cert, key = secret_file("GEOTRAJ_TLS_CERT"), secret_file("GEOTRAJ_TLS_KEY")
        if not cert or not key:
            fail("TLS: certificate and key must both come from a mounted Secret")
        if env.get("GEOTRAJ_PLAINTEXT", "false").lower() in ("true", "1", "yes", "on"):
            fail("TLS configured, but GEOTRAJ_PLAINTEXT is still true")
        if env.get("GEOTRAJ_TLS_CLIENT_CA"):
            secret_file("GEOTRAJ_TLS_CLIENT_CA")
    elif env.get("GEOTRAJ_PLAINTEXT", "").lower() != "true" and not env.get("GEOTRAJ_ADDRESS", "").startswith("127."):
        fail("no TLS and GEOTRAJ_PLAINTEXT is not true: geotrajd would refuse to start on a non-loopback address")

    # Topology spread selects the pods.
    for tsc in pod.get("topologySpreadConstraints", []):
        if not selects(tsc.get("labelSelector", {}).get("matchLabels"), pod_labels):
            fail("topologySpreadConstraints labelSelector does not select the pods")

    # Services.
    services = by_kind.get("Service", [])
    headless = [s for s in services if s["spec"].get("clusterIP") == "None"]
    if len(headless) != 1:
        fail(f"{len(headless)} headless Services: expected 1 (client-side round_robin over pod addresses)")
    for s in services:
        sname = s["metadata"]["name"]
        if not selects(s["spec"].get("selector"), pod_labels):
            fail(f"Service {sname}: selector {s['spec'].get('selector')} does not select the pods {pod_labels}")
        for p in s["spec"].get("ports", []):
            target = p.get("targetPort", p["port"])
            resolved = port_names.get(target) if isinstance(target, str) else target
            if resolved not in ports:
                fail(f"Service {sname}: targetPort {target} is not a container port")
    for s in headless:
        tports = {port_names.get(p.get("targetPort")) if isinstance(p.get("targetPort"), str) else p.get("targetPort", p["port"])
                  for p in s["spec"].get("ports", [])}
        if grpc_port not in tports:
            fail(f"headless Service {s['metadata']['name']} does not serve the gRPC port {grpc_port}")
        if any(p["port"] != (port_names.get(p.get("targetPort")) if isinstance(p.get("targetPort"), str) else p.get("targetPort", p["port"]))
               for p in s["spec"].get("ports", [])):
            fail("headless Service: port and targetPort differ; DNS gives pod addresses, so clients use the pod's port")

    # HPA and PDB.
    hpas = by_kind.get("HorizontalPodAutoscaler", [])
    if len(hpas) != 1:
        fail(f"{len(hpas)} HorizontalPodAutoscalers: expected 1")
    for h in hpas:
        ref = h["spec"]["scaleTargetRef"]
        if (ref.get("apiVersion"), ref.get("kind"), ref.get("name")) != ("apps/v1", "Deployment", dname):
            fail(f"HPA {h['metadata']['name']} targets {ref}, not Deployment {dname}")
        if h["spec"].get("minReplicas", 1) > h["spec"]["maxReplicas"]:
            fail("HPA minReplicas > maxReplicas")
        cpu = [m for m in h["spec"].get("metrics", []) if m.get("type") == "Resource" and m["resource"]["name"] == "cpu"]
        if not cpu:
            fail("HPA does not scale on CPU")
        replicas = min(replicas, h["spec"].get("minReplicas", 1))
    pdbs = by_kind.get("PodDisruptionBudget", [])
    if len(pdbs) != 1:
        fail(f"{len(pdbs)} PodDisruptionBudgets: expected 1")
    for p in pdbs:
        if not selects(p["spec"]["selector"].get("matchLabels"), pod_labels):
            fail(f"PDB {p['metadata']['name']} does not select the Deployment's pods")
        min_available = p["spec"].get("minAvailable")
        if not isinstance(min_available, int) or not 1 <= min_available < replicas:
            fail(f"PDB minAvailable {min_available}: expected an integer from 1 to below the replicas ({replicas})")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("directory")
    parser.add_argument("--kustomize", help="a kustomize binary, or kubectl (kubectl kustomize)")
    parser.add_argument("--compare", action="store_true", help="also render here and compare with kustomize")
    parser.add_argument("--expect-tls", action="store_true")
    parser.add_argument("--secret-example", help="default: secret.example.yaml in deploy/k8s")
    args = parser.parse_args()

    if args.kustomize:
        objects = kustomize_build(args.kustomize, args.directory)
        print(f"rendered {args.directory} with {args.kustomize}: {len(objects)} objects")
        if args.compare:
            mine = render(args.directory)
            if normalised(mine) != normalised(objects):
                import difflib
                diff = difflib.unified_diff(normalised(objects).splitlines(), normalised(mine).splitlines(),
                                            "kustomize", "kustomize_check.py", lineterm="", n=2)
                fail("the renderer here and kustomize disagree:\n" + "\n".join(diff))
            else:
                print("the renderer here agrees with kustomize (up to the ConfigMap's hash suffix)")
    else:
        objects = render(args.directory)
        print(f"rendered {args.directory} here (no kustomize): {len(objects)} objects")
    secret_example = args.secret_example
    if secret_example is None:
        for candidate in (os.path.join(args.directory, "secret.example.yaml"),
                          os.path.join(args.directory, "..", "k8s", "secret.example.yaml")):
            if os.path.exists(candidate):
                secret_example = candidate
                break
    check(copy.deepcopy(objects), secret_example, args.expect_tls)
    if FAILURES:
        print(f"{len(FAILURES)} failure(s)", file=sys.stderr)
        return 1
    print(f"kustomize_check {args.directory}: OK ({', '.join(sorted(o['kind'] + '/' + o['metadata']['name'] for o in objects))})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
