#!/usr/bin/env python3
"""deploy/check-deploy.py - checks deploy/ against the binaries it runs (make check-deploy,
part of make test).

Usage: check-deploy.py SEAMTEXD SEAMTEX   (the built daemon and CLI)

Checks:
  - every deploy/k8s/*.yaml parses (PyYAML, Debian python3-yaml) and every document in it has
    apiVersion, kind and metadata.name; kustomization.yaml lists every other manifest;
  - every seamtexd flag the deployment files use (k8s container args, the Containerfile's CMD,
    the systemd unit's ExecStart, the keys of seamtexd.conf.example) is listed by
    `seamtexd --help`;
  - every probe and HEALTHCHECK runs `seamtex ... ping` with options `seamtex --help` lists;
  - the prometheus.io/port annotation is the port of --metrics-listen and a containerPort;
  - when kubectl is installed, `kubectl kustomize deploy/k8s` renders (offline, no cluster).
Exit status 0 when all hold, 1 with one line per problem otherwise.
"""
import glob
import os
import re
import shlex
import shutil
import subprocess
import sys

import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
problems = []


def problem(msg):
    problems.append(msg)


def help_flags(binary):
    out = subprocess.run([binary, "--help"], capture_output=True, text=True, timeout=30)
    text = out.stdout + out.stderr
    flags = set(re.findall(r"(?m)^\s+(?:-\w,\s*)?--([a-z0-9][a-z0-9-]*)", text))
    flags |= set(re.findall(r"(?m)^\s+-(\w)\b", text))      # short options ("-h HOST")
    flags |= set(re.findall(r"\[(-\w) ", text))               # usage line "[-h HOST]"
    flags |= set(re.findall(r"\[(--[a-z-]+) ", text))
    return {f.lstrip("-") for f in flags}, text


def flags_of(args):
    """The --flag names in an argument list (--flag value or --flag=value)."""
    return [a[2:].split("=", 1)[0] for a in args if isinstance(a, str) and a.startswith("--")]


def main():
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    seamtexd, seamtex = sys.argv[1], sys.argv[2]
    daemon_flags, _ = help_flags(seamtexd)
    cli_flags, cli_help = help_flags(seamtex)
    if "listen" not in daemon_flags:
        problem(f"{seamtexd} --help lists no --listen: cannot check flags")
    used = []   # (where, flag)

    # ---- Kubernetes manifests ---------------------------------------------------------------
    manifests = sorted(glob.glob(os.path.join(ROOT, "deploy/k8s/*.yaml")))
    if not manifests:
        problem("no deploy/k8s/*.yaml")
    names = set()
    for path in manifests:
        rel = os.path.relpath(path, ROOT)
        try:
            with open(path) as f:
                docs = [d for d in yaml.safe_load_all(f) if d is not None]
        except yaml.YAMLError as e:
            problem(f"{rel}: does not parse: {e}")
            continue
        for d in docs:
            if not isinstance(d, dict) or not d.get("apiVersion") or not d.get("kind"):
                problem(f"{rel}: a document without apiVersion and kind")
                continue
            if d["kind"] == "Kustomization":
                listed = set(d.get("resources", []))
                others = {os.path.basename(p) for p in manifests} - {os.path.basename(path)}
                for m in sorted(others - listed):
                    problem(f"{rel}: does not list {m}")
                continue
            if not (d.get("metadata") or {}).get("name"):
                problem(f"{rel}: {d['kind']} without metadata.name")
            names.add((d["kind"], d["metadata"]["name"]))
            tmpl = ((d.get("spec") or {}).get("template") or {})
            pod = tmpl.get("spec") or {}
            ann = (tmpl.get("metadata") or {}).get("annotations") or {}
            for c in pod.get("containers", []):
                cmd = (c.get("command") or []) + (c.get("args") or [])
                is_seamtexd = c.get("name") == "seamtexd"
                if is_seamtexd:
                    for fl in flags_of(cmd):
                        used.append((f"{rel} ({d['kind']} {d['metadata']['name']})", fl))
                    args = c.get("args") or []
                    mport = None
                    for i, a in enumerate(args):
                        if a == "--metrics-listen" and i + 1 < len(args):
                            mport = args[i + 1].rsplit(":", 1)[-1]
                    ports = {str(p.get("containerPort")) for p in c.get("ports", [])}
                    if ann.get("prometheus.io/scrape") == "true":
                        if str(ann.get("prometheus.io/port")) != str(mport):
                            problem(f"{rel}: prometheus.io/port {ann.get('prometheus.io/port')} "
                                    f"is not the --metrics-listen port {mport}")
                        if str(mport) not in ports:
                            problem(f"{rel}: no containerPort {mport} for the metrics")
                    elif mport:
                        problem(f"{rel}: --metrics-listen without prometheus.io/scrape annotations")
                    for probe in ("readinessProbe", "livenessProbe", "startupProbe"):
                        pr = c.get(probe)
                        if not pr:
                            if probe != "startupProbe":
                                problem(f"{rel}: seamtexd container has no {probe}")
                            continue
                        check_ping(f"{rel} {probe}", (pr.get("exec") or {}).get("command"),
                                   cli_flags, cli_help)
    kubectl = shutil.which("kubectl")
    if kubectl:
        r = subprocess.run([kubectl, "kustomize", os.path.join(ROOT, "deploy/k8s")],
                           capture_output=True, text=True, timeout=120)
        if r.returncode != 0:
            problem(f"kubectl kustomize deploy/k8s failed: {r.stderr.strip()[:300]}")
    for want in (("StatefulSet", "etcd"), ("StatefulSet", "seamtexd"),
                 ("PodDisruptionBudget", "seamtexd")):
        if want not in names:
            problem(f"deploy/k8s: no {want[0]} {want[1]}")

    # ---- Containerfile ----------------------------------------------------------------------
    cf = os.path.join(ROOT, "deploy/Containerfile")
    text = open(cf).read().replace("\\\n", " ")
    m = re.search(r"(?m)^CMD\s+(\[.*\])\s*$", text)
    if not m:
        problem("deploy/Containerfile: no CMD [...] line")
    else:
        for fl in flags_of(yaml.safe_load(m.group(1))):
            used.append(("deploy/Containerfile CMD", fl))
    m = re.search(r"(?m)^HEALTHCHECK\b.*?CMD\s+(\[.*\])\s*$", text)
    if not m:
        problem("deploy/Containerfile: no HEALTHCHECK ... CMD [...]")
    else:
        check_ping("deploy/Containerfile HEALTHCHECK", yaml.safe_load(m.group(1)), cli_flags,
                   cli_help)

    # ---- systemd unit and config example ----------------------------------------------------
    unit = open(os.path.join(ROOT, "deploy/seamtexd.service")).read()
    m = re.search(r"(?m)^ExecStart=(.*)$", unit)
    if m:
        for fl in flags_of(shlex.split(m.group(1))):
            if fl != "config":   # --config is not a settings key; --help shows it apart
                used.append(("deploy/seamtexd.service ExecStart", fl))
    for line in open(os.path.join(ROOT, "deploy/seamtexd.conf.example")):
        line = line.split("#", 1)[0].strip()
        if "=" in line:
            used.append(("deploy/seamtexd.conf.example", line.split("=", 1)[0].strip()))

    for where, fl in used:
        if fl in daemon_flags or fl == "config":
            continue
        problem(f"{where}: seamtexd --{fl} is not in `seamtexd --help`")

    for p in problems:
        print(f"check-deploy: {p}", file=sys.stderr)
    if problems:
        return 1
    print(f"check-deploy: {len(manifests)} manifests parse; {len(used)} seamtexd flag uses "
          f"checked against --help; probes and metrics annotations consistent")
    return 0


def check_ping(where, cmd, cli_flags, cli_help):
    if not cmd or os.path.basename(cmd[0]) != "seamtex" or cmd[-1] != "ping":
        problem(f"{where}: not `seamtex ... ping`: {cmd}")
        return
    if not re.search(r"(?m)^\s+ping\b", cli_help):
        problem(f"{where}: `seamtex --help` lists no ping command")
    for a in cmd[1:-1]:
        if a.startswith("-") and a.lstrip("-") not in cli_flags:
            problem(f"{where}: seamtex option {a} is not in `seamtex --help`")


if __name__ == "__main__":
    sys.exit(main())
