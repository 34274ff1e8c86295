#!/usr/bin/env python3
"""Checks the Kubernetes manifests under deploy/ without a cluster (docs/deployment.md).

Every YAML file parses; each kustomization's resources and patches exist; its patches are
applied here the way kustomize's strategic merge applies them (containers, volumes and mounts
merged by name, a null removes a key, other lists replaced); and every resulting Deployment
and Service is checked for what a cluster would refuse or what would break Fulcrum quietly:
selectors that match the pod labels, probes with one handler on a declared port, fulcrum-server
flags that exist (against the built binary's --help), a termination grace period longer than
--grace-ms, resource requests, volumes for every mount and a Secret behind every secret volume.
Agones Fleets and GameServers (plain YAML files) get the same pod checks, and must run the
server with --agones, ping Health more often than their health period, and map port 50051.

usage: check_manifests.py DEPLOY_DIR FULCRUM_SERVER_BINARY
"""
import copy
import os
import re
import subprocess
import sys

import yaml

failures = []


def fail(where, what):
    failures.append(f"{where}: {what}")


def load_all(path):
    with open(path, encoding="utf-8") as f:
        return [d for d in yaml.safe_load_all(f) if d is not None]


MERGE_KEYS = {"containers": "name", "volumes": "name", "volumeMounts": "mountPath",
              "ports": "containerPort", "env": "name"}


def merge(base, patch):
    """Strategic merge of `patch` into `base` for the fields these manifests use."""
    if not isinstance(base, dict) or not isinstance(patch, dict):
        return copy.deepcopy(patch)
    out = copy.deepcopy(base)
    for key, value in patch.items():
        if value is None:
            out.pop(key, None)
        elif key in MERGE_KEYS and isinstance(value, list) and isinstance(out.get(key), list):
            by = MERGE_KEYS[key]
            merged = list(out[key])
            for item in value:
                index = next((i for i, old in enumerate(merged)
                              if isinstance(old, dict) and old.get(by) == item.get(by)), None)
                if index is None:
                    merged.append(copy.deepcopy(item))
                else:
                    merged[index] = merge(merged[index], item)
            out[key] = merged
        elif key in out:
            out[key] = merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def build(directory):
    """The objects `kubectl apply -k directory` would apply."""
    kustomization = load_all(os.path.join(directory, "kustomization.yaml"))[0]
    objects = []
    for resource in kustomization.get("resources", []):
        path = os.path.normpath(os.path.join(directory, resource))
        if os.path.isdir(path):
            objects += build(path)
        elif os.path.isfile(path):
            objects += load_all(path)
        else:
            fail(directory, f"resource {resource} does not exist")
    for patch in kustomization.get("patches", []):
        path = os.path.join(directory, patch["path"])
        if not os.path.isfile(path):
            fail(directory, f"patch {patch['path']} does not exist")
            continue
        for p in load_all(path):
            target = [o for o in objects if o.get("kind") == p.get("kind")
                      and o["metadata"]["name"] == p["metadata"]["name"]]
            if len(target) != 1:
                fail(path, f"patches {p.get('kind')}/{p['metadata']['name']}, which is not there")
                continue
            objects[objects.index(target[0])] = merge(target[0], p)
    return objects


def server_flags(binary):
    help_text = subprocess.run([binary, "--help"], capture_output=True, text=True).stdout
    return set(re.findall(r"^  --([a-z0-9-]+)", help_text, re.M))


def check_probe(where, probe, ports):
    handlers = [h for h in ("grpc", "exec", "httpGet", "tcpSocket") if h in probe]
    if len(handlers) != 1:
        fail(where, f"needs exactly one handler, has {handlers}")
        return
    if "grpc" in probe and probe["grpc"].get("port") not in ports.values():
        fail(where, f"grpc port {probe['grpc'].get('port')} is not a container port")
    if "exec" in probe:
        command = probe["exec"].get("command", [])
        if command[:2] != ["fulcrum", "health"]:
            fail(where, f"runs {command[:2]}, not `fulcrum health`")


def check_container_args(cw, c, flags, grace_s):
    """Flags that exist, a termination grace above --grace-ms, files on mounted volumes."""
    args = c.get("args", [])
    for a in args:
        name = re.match(r"--([a-z0-9-]+)", a)
        if not name or name.group(1) not in flags:
            fail(cw, f"{a!r} is not a fulcrum-server flag")
    grace = [int(a.split("=", 1)[1]) for a in args if a.startswith("--grace-ms=")]
    grace_ms = grace[-1] if grace else 5000
    if grace_s * 1000 <= grace_ms:
        fail(cw, f"terminationGracePeriodSeconds {grace_s} s is not above --grace-ms "
                 f"{grace_ms} ms")
    mounts = [m["mountPath"].rstrip("/") for m in c.get("volumeMounts", [])]
    for a in args:
        if a.startswith(("--token-file=", "--tls-cert=", "--tls-key=", "--replay-dir=")):
            path = a.split("=", 1)[1]
            if not any(path == m or path.startswith(m + "/") for m in mounts):
                fail(cw, f"{a} is on no mounted volume")
    return args


def check_pod(where, pod_spec, flags, probes_required):
    """A pod spec's containers: image, probes, requests, mounts, arguments."""
    volumes = {v["name"]: v for v in pod_spec.get("volumes", [])}
    for v in volumes.values():
        if "secret" in v and not v["secret"].get("secretName"):
            fail(where, f"volume {v['name']} names no Secret")
    grace_s = pod_spec.get("terminationGracePeriodSeconds", 30)
    all_args = []
    for c in pod_spec["containers"]:
        cw = f"{where} container {c['name']}"
        if not c.get("image"):
            fail(cw, "no image")
        ports = {p.get("name"): p["containerPort"] for p in c.get("ports", [])}
        for name in ("readinessProbe", "livenessProbe"):
            if name in c:
                check_probe(f"{cw} {name}", c[name], ports)
            elif probes_required:
                fail(cw, f"no {name}")
        requests = c.get("resources", {}).get("requests", {})
        if "cpu" not in requests or "memory" not in requests:
            fail(cw, "resources.requests needs cpu and memory")
        for m in c.get("volumeMounts", []):
            if m["name"] not in volumes:
                fail(cw, f"mounts {m['name']}, which is not a volume")
        all_args += check_container_args(cw, c, flags, grace_s)
    return all_args


def check_deployment(where, d, flags):
    spec = d["spec"]
    pod = spec["template"]
    labels = pod["metadata"].get("labels", {})
    for k, v in spec["selector"]["matchLabels"].items():
        if labels.get(k) != v:
            fail(where, f"selector {k}={v} does not match the pod labels {labels}")
    check_pod(where, pod["spec"], flags, probes_required=True)
    return {p.get("name"): p["containerPort"]
            for c in pod["spec"]["containers"] for p in c.get("ports", [])}, labels


def check_gameserver(where, spec, flags):
    """An Agones GameServer spec (alone or a Fleet's template): the server runs with --agones,
    pings Health well within the period Agones allows, and serves on the declared port."""
    args = check_pod(where, spec["template"]["spec"], flags, probes_required=False)
    if "--agones" not in args:
        fail(where, "the server does not run with --agones (it would never become Ready)")
    health = spec.get("health", {})
    period_ms = health.get("periodSeconds", 5) * 1000
    pings = [int(a.split("=", 1)[1]) for a in args if a.startswith("--agones-health-ms=")]
    ping_ms = pings[-1] if pings else 2000
    if not ping_ms < period_ms:
        fail(where, f"--agones-health-ms {ping_ms} is not below health.periodSeconds "
                    f"({period_ms} ms): Agones would mark the server Unhealthy")
    ports = spec.get("ports", [])
    if not any(p.get("containerPort") == 50051 for p in ports):
        fail(where, "no port maps to 50051, where the image's entry point listens")


def check_service(where, s, pods):
    for labels, ports in pods:
        if all(labels.get(k) == v for k, v in s["spec"]["selector"].items()):
            for p in s["spec"]["ports"]:
                target = p.get("targetPort", p["port"])
                if target not in ports and target not in ports.values():
                    fail(where, f"targetPort {target} is no container port of its pods")
            return
    fail(where, f"selector {s['spec']['selector']} matches no Deployment's pods")


def main():
    deploy, binary = sys.argv[1], sys.argv[2]
    flags = server_flags(binary)
    if "grace-ms" not in flags:
        fail(binary, "--help lists no flags")
    files = 0
    for root, _, names in os.walk(deploy):
        for n in sorted(names):
            if n.endswith((".yaml", ".yml")):
                files += 1
                try:
                    load_all(os.path.join(root, n))
                except yaml.YAMLError as e:
                    fail(os.path.join(root, n), f"does not parse: {e}")
    checked = 0
    for root, _, names in os.walk(deploy):
        if "kustomization.yaml" not in names:
            continue
        objects = build(root)
        pods = []
        for o in objects:
            for key in ("apiVersion", "kind", "metadata"):
                if key not in o:
                    fail(root, f"an object without {key}")
            if o.get("kind") == "Deployment":
                ports, labels = check_deployment(f"{root}: Deployment/{o['metadata']['name']}",
                                                 o, flags)
                pods.append((labels, ports))
                checked += 1
        for o in objects:
            if o.get("kind") == "Service":
                check_service(f"{root}: Service/{o['metadata']['name']}", o, pods)
                checked += 1
    for root, _, names in os.walk(deploy):
        for n in sorted(names):
            if not n.endswith((".yaml", ".yml")) or "kustomization.yaml" in names:
                continue
            path = os.path.join(root, n)
            for o in load_all(path):
                if o.get("kind") == "Fleet":
                    check_gameserver(f"{path}: Fleet/{o['metadata']['name']}",
                                     o["spec"]["template"]["spec"], flags)
                    checked += 1
                elif o.get("kind") == "GameServer":
                    check_gameserver(f"{path}: GameServer", o["spec"], flags)
                    checked += 1
    for f in failures:
        print("FAIL:", f)
    print(f"{files} YAML files parsed, {checked} objects checked, {len(failures)} problems")
    return 1 if failures or checked == 0 else 0


if __name__ == "__main__":
    sys.exit(main())
