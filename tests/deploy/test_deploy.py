"""deploy/ against the code: the command lines the compose file, the Kubernetes manifests and the
systemd units run parse with the real `ig` parser, the rig files they mount load and are not
refused by the plaintext rule, and every port, probe and replica count agrees with the rig file;
every port Prometheus scrapes (deploy/prometheus/) is a metrics port a service serves and exposes.

A port changed in a rig file, or a flag renamed in the CLI, fails here until deploy/ follows.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import io
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

from services.cli import build_parser
from services.rig.cli_common import metrics_address_of
from services.rig.grpc_util import is_loopback
from services.rig.rigfile import Rig, load_rig, port_of

ROOT = Path(__file__).resolve().parents[2]
DEPLOY = ROOT / "deploy"
RIGS = DEPLOY / "rigs"
DOCKER = DEPLOY / "docker"
K8S = DEPLOY / "k8s"
SYSTEMD = DEPLOY / "systemd"
PROMETHEUS = DEPLOY / "prometheus"

#: Where every deployment mounts the rig file.
RIG_PATH = "/etc/ig/rig.toml"
#: The rig file the systemd units are written for (deploy/README.md: copy it to /etc/ig/rig.toml).
SYSTEMD_RIG = RIGS / "three-machines.toml"
SERVICES = ("host", "compositor", "worker")


def _ig_health():
    spec = importlib.util.spec_from_file_location("ig_health", DOCKER / "ig_health.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# -- helpers: command lines, rigs, the plaintext rule ---------------------------------------------

def parse_ig(args: list[str], where: str) -> argparse.Namespace:
    """args (from the subcommand on) parsed by the real `ig` parser; fails on an unknown flag."""
    parser = build_parser(args[0])
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            parsed = parser.parse_args(args)
    except SystemExit:
        pytest.fail(f"{where}: `ig {shlex.join(args)}` does not parse: {err.getvalue().strip()}")
    # argparse also takes an unambiguous prefix of a flag (--out for --output): deploy/ spells them out.
    [sub] = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    known = sub.choices[args[0]]._option_string_actions
    unknown = [a.split("=")[0] for a in args if a.startswith("--") and a.split("=")[0] not in known]
    assert not unknown, f"{where}: `ig {args[0]}` has no flag {unknown} (only a prefix of one)"
    return parsed


def ig_args(argv: list[str]) -> list[str] | None:
    """The `ig` arguments of a command line (argv[0] is ig or a path to it), else None."""
    if argv and Path(argv[0]).name == "ig":
        return argv[1:]
    return None


def address_of(args: argparse.Namespace, rig: Rig) -> str:
    """The rig address of the service an `ig host|compositor|worker` command line starts."""
    if args.command == "host":
        return rig.host_address
    if args.command == "compositor":
        return rig.compositor_address
    if args.channel_index is not None:
        assert 0 <= args.channel_index < len(rig.channels), f"--channel-index {args.channel_index} out of the rig"
        return rig.channels[args.channel_index].address
    return rig.channel(args.channel).address


def metrics_of(args: argparse.Namespace, rig: Rig) -> str | None:
    """host:port the metrics of an `ig host|compositor|worker` command line listen on (None: none)."""
    if args.command == "host":
        port = rig.host_metrics_port
    elif args.command == "compositor":
        port = rig.compositor_metrics_port
    else:
        port = next(c for c in rig.channels if c.address == address_of(args, rig)).metrics_port
    return metrics_address_of(args, port)


def assert_scrapable(args: argparse.Namespace, rig: Rig, where: str) -> int:
    """The port of a service's metrics, which a Prometheus in another container or pod reaches;
    returns it."""
    metrics = metrics_of(args, rig)
    assert metrics is not None, f"{where}: no metrics port (the rig file's metrics_port or --metrics-port)"
    assert args.metrics_bind == "0.0.0.0", f"{where}: metrics on the loopback only, out of Prometheus's reach"
    return port_of(metrics)


def channel_of(args: argparse.Namespace, rig: Rig) -> str:
    return rig.channels[args.channel_index].name if args.channel_index is not None else args.channel


def assert_not_refused(rig: Rig, binds: list[str | None]) -> None:
    """What grpc_util refuses: plaintext off the loopback without tls.allow_plaintext, for every
    address a service connects to and every address it listens on."""
    if rig.tls.enabled or rig.tls.allow_plaintext:
        return
    addresses = [rig.host_address, rig.compositor_address, *(c.address for c in rig.channels)]
    listens = [a if b is None else f"{b}:{port_of(a)}" for a in addresses for b in binds]
    off = [a for a in addresses + listens if not is_loopback(a)]
    assert not off, f"{rig.source}: plaintext off the loopback ({', '.join(off)}) without [tls] or allow_plaintext"


def test_every_deploy_rig_loads_and_is_not_refused():
    # At its own addresses; the deployments below add the --bind they listen with.
    for path in sorted(RIGS.glob("*.toml")):
        assert_not_refused(load_rig(path), [None])


# -- the image ------------------------------------------------------------------------------------

def test_dockerfile_runs_ig_with_its_health_check_as_a_user():
    text = (DOCKER / "Dockerfile").read_text()
    assert re.search(r"^FROM python:3\.11-slim", text, re.M)
    assert re.search(r"pip install '\.\[devices\]'", text)
    assert re.search(r'^ENTRYPOINT \["ig"\]', text, re.M)
    assert re.search(r'^HEALTHCHECK .*CMD \["ig-health"\]', text, re.M)
    assert "deploy/docker/ig_health.py /usr/local/bin/ig-health" in text
    user = re.findall(r"^USER (\S+)", text, re.M)
    assert user and user[-1] not in ("root", "0")


def test_ig_health_finds_the_service_and_its_port():
    health = _ig_health()
    cmdlines = [["/sbin/init"], ["/usr/local/bin/python3.11", "/usr/local/bin/ig", "worker", "--rig", "r.toml",
                                 "--channel-index", "1", "--bind", "0.0.0.0"]]
    assert health.service_argv(cmdlines) == cmdlines[1][2:]
    with pytest.raises(LookupError):
        health.service_argv([["ig", "demo"]])
    rig = RIGS / "compose.toml"
    target, name, _ = health.probe_target(["worker", "--rig", str(rig), "--channel-index", "1", "--bind", "0.0.0.0"])
    assert (target, name) == (f"127.0.0.1:{port_of(load_rig(rig).channels[1].address)}", "worker-centre")
    target, _, _ = health.probe_target(["host", "--rig", str(rig)])
    assert target == load_rig(rig).host_address


# -- docker compose -------------------------------------------------------------------------------

def _compose() -> dict[str, Any]:
    return yaml.safe_load((DOCKER / "compose.yaml").read_text())


def _mounted_rig(volumes: list[str], base: Path) -> Path:
    for v in volumes:
        source, _, rest = v.partition(":")
        if rest.split(":")[0] == RIG_PATH:
            assert rest.endswith(":ro"), f"{v}: the rig file is mounted read-only"
            return (base / source).resolve()
    pytest.fail(f"no volume mounts {RIG_PATH}: {volumes}")


def test_compose_services_match_the_rig():
    compose = _compose()
    channels: dict[str, str] = {}
    counts = dict.fromkeys(SERVICES, 0)
    rig_path = None
    for name, svc in compose["services"].items():
        if svc.get("image") != "ig-rig:latest":
            continue  # Prometheus (test_compose_prometheus_scrapes_every_service)
        args = svc["command"]
        parsed = parse_ig(args, f"compose.yaml: {name}")
        path = _mounted_rig(svc["volumes"], DOCKER)
        assert path.parent == RIGS and path.exists(), f"{name}: {path} is not a rig of deploy/rigs"
        assert parsed.rig == RIG_PATH, f"{name}: --rig {parsed.rig}, mounted at {RIG_PATH}"
        assert rig_path in (None, path), f"{name}: mounts {path}, others {rig_path}"
        rig_path = path
        rig = load_rig(path)
        assert svc.get("restart") in ("always", "unless-stopped", "on-failure", "no"), name
        if parsed.command == "compile":
            assert svc["restart"] == "no"
            continue
        counts[parsed.command] += 1
        assert parsed.bind == "0.0.0.0", f"{name}: another container cannot reach a service without --bind"
        assert_not_refused(rig, [parsed.bind])
        address = address_of(parsed, rig)
        assert address.rpartition(":")[0] == name, f"{name}: its rig address is {address}"
        metrics = assert_scrapable(parsed, rig, f"compose.yaml: {name}")
        assert [int(p) for p in svc.get("expose", [])] == [port_of(address), metrics], \
            f"{name}: expose vs rig {address} and metrics port {metrics}"
        # The health check: ig-health, which asks grpc.health.v1.Health at the port of the
        # service's own command line.
        check = svc["healthcheck"]
        assert not check.get("disable") and check["test"][:2] == ["CMD", "ig-health"], name
        target, _, _ = _ig_health().probe_target([str(path) if a == RIG_PATH else a for a in args])
        assert port_of(target) == port_of(address)
        assert svc.get("stop_signal", "SIGTERM") == "SIGTERM"
        if parsed.command == "worker":
            channel = channel_of(parsed, rig)
            assert channel not in channels, f"{name} and {channels.get(channel)} both render {channel}"
            channels[channel] = name
        if parsed.command == "compositor":
            outs = [v for v in svc["volumes"] if v.split(":")[1] == parsed.out]
            assert outs and outs[0].split(":")[0] in compose["volumes"], f"{name}: --out is a named volume"
    assert counts == {"host": 1, "compositor": 1, "worker": len(rig.channels)}
    assert sorted(channels) == sorted(rig.channel_names)
    kernels = {v.split(":")[0] for s in compose["services"].values() for v in s["volumes"]
               if v.split(":")[1] == "/var/cache/ig"}
    assert kernels <= set(compose["volumes"]) and len(kernels) == 1, "one shared kernel cache volume"


def test_compose_prometheus_scrapes_every_service():
    compose = _compose()
    exposed = {}
    for name, svc in compose["services"].items():
        if svc.get("image") == "ig-rig:latest" and svc["command"][0] != "compile":
            parsed = parse_ig(svc["command"], name)
            rig = load_rig(_mounted_rig(svc["volumes"], DOCKER))
            exposed[name] = (port_of(metrics_of(parsed, rig)), [int(p) for p in svc["expose"]])
    prometheus = compose["services"]["prometheus"]
    assert prometheus["profiles"] == ["monitoring"], "Prometheus only when asked for"
    assert "rig" in prometheus["networks"], "Prometheus reaches the services on the rig's network"
    assert all(p.startswith("127.0.0.1:") for p in prometheus["ports"]), "its UI on the loopback only"
    config = [v.split(":")[0] for v in prometheus["volumes"] if v.split(":")[1] == "/etc/prometheus/prometheus.yml"]
    assert [(DOCKER / c).resolve() for c in config] == [PROMETHEUS / "compose.yml"]
    targets = [t for job in yaml.safe_load((PROMETHEUS / "compose.yml").read_text())["scrape_configs"]
               for group in job["static_configs"] for t in group["targets"]]
    for target in targets:
        host, _, port = target.rpartition(":")
        assert host in exposed, f"prometheus/compose.yml: {target}: no such service"
        assert int(port) == exposed[host][0] and int(port) in exposed[host][1], \
            f"prometheus/compose.yml: {target}: {host} serves its metrics at {exposed[host][0]}"
    assert sorted(t.rpartition(":")[0] for t in targets) == sorted(exposed), "every service scraped, once"


def test_compose_config_validates():
    docker = shutil.which("docker")
    if docker is None:
        pytest.skip("no docker CLI")
    probe = subprocess.run([docker, "compose", "version"], capture_output=True, text=True, timeout=30)
    if probe.returncode != 0:
        pytest.skip(f"the docker CLI has no compose plugin: {probe.stderr.strip()[:200]}")
    result = subprocess.run([docker, "compose", "-f", str(DOCKER / "compose.yaml"), "config", "-q"],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr


# -- Kubernetes ------------------------------------------------------------------------------------

def _manifests() -> list[dict[str, Any]]:
    docs = []
    for path in sorted(K8S.glob("*.yaml")):
        if path.name != "kustomization.yaml":
            docs += [d for d in yaml.safe_load_all(path.read_text()) if d]
    return docs


def _k8s_rig() -> tuple[Rig, str]:
    maps = [d for d in _manifests() if d["kind"] == "ConfigMap"]
    assert len(maps) == 1
    text = maps[0]["data"]["rig.toml"]
    rig_path = RIGS / "k8s.toml"
    assert text == rig_path.read_text(), "deploy/k8s/configmap.yaml differs from deploy/rigs/k8s.toml"
    return load_rig(rig_path), maps[0]["metadata"]["name"]


def _commands(container: dict[str, Any], ordinals: range | None) -> list[list[str]]:
    """The `ig` arguments the container runs (for each pod ordinal of a StatefulSet)."""
    argv = container.get("command", ["ig"]) + container.get("args", [])  # the image's ENTRYPOINT is ig
    if argv[:2] == ["sh", "-c"]:
        words = shlex.split(argv[2])
        assert words[0] == "exec", f"{container['name']}: `exec ig ...`, so that SIGTERM reaches ig"
        argv = words[1:]
    out = []
    for i in ordinals or [None]:
        args = ig_args([str(i) if (w == "${HOSTNAME##*-}" and i is not None) else w for w in argv])
        assert args is not None, f"{container['name']}: {argv} does not run ig"
        out.append(args)
    return out


def _matches(selector: dict[str, str], labels: dict[str, str]) -> bool:
    return all(labels.get(k) == v for k, v in selector.items())


def _probes(container: dict[str, Any], port: int, rig: Rig) -> None:
    for kind in ("startupProbe", "readinessProbe", "livenessProbe"):
        probe = container.get(kind)
        assert probe, f"{container['name']}: no {kind}"
        if "grpc" in probe:
            # Kubernetes' gRPC probe: plaintext, no client certificate.
            assert not rig.tls.enabled, f"{container['name']}: a grpc {kind} cannot pass the rig's mutual TLS"
            assert probe["grpc"]["port"] == port and probe["grpc"].get("service", "") == ""
        else:
            assert probe["exec"]["command"] == ["ig-health"], f"{container['name']}: {kind}"


def _mounted_files(spec: dict[str, Any], container: dict[str, Any]) -> set[str]:
    """Files the container sees from Secret volumes with items, and emptyDirs filled by an init
    container that names them."""
    volumes = {v["name"]: v for v in spec.get("volumes", [])}
    files = set()
    for m in container.get("volumeMounts", []):
        v = volumes[m["name"]]
        if "secret" in v and "items" in v["secret"]:
            files |= {f"{m['mountPath']}/{item['path']}" for item in v["secret"]["items"]}
        if "emptyDir" in v:
            for init in spec.get("initContainers", []):
                script = " ".join(init.get("command", []) + init.get("args", []))
                files |= set(re.findall(re.escape(m["mountPath"]) + r"/[\w.-]+", script))
    return files


def test_k8s_workloads_match_the_rig():
    rig, configmap = _k8s_rig()
    docs = _manifests()
    namespaces = {d["metadata"]["name"] for d in docs if d["kind"] == "Namespace"}
    services = [d for d in docs if d["kind"] == "Service"]
    workloads = [d for d in docs if d["kind"] in ("Deployment", "StatefulSet")]
    seen = dict.fromkeys(SERVICES, 0)
    channels = []
    for w in workloads:
        name, ns = w["metadata"]["name"], w["metadata"]["namespace"]
        assert ns in namespaces
        spec = w["spec"]["template"]["spec"]
        labels = w["spec"]["template"]["metadata"]["labels"]
        assert _matches(w["spec"]["selector"]["matchLabels"], labels)
        assert spec.get("terminationGracePeriodSeconds", 0) >= 10, f"{name}: time to exit on SIGTERM"
        sts = w["kind"] == "StatefulSet"
        if sts:
            assert w["spec"]["replicas"] == len(rig.channels), f"{name}: one pod per channel"
            terms = spec["affinity"]["podAntiAffinity"]["requiredDuringSchedulingIgnoredDuringExecution"]
            assert any(t["topologyKey"] == "kubernetes.io/hostname" and _matches(t["labelSelector"]["matchLabels"],
                                                                                   labels) for t in terms)
        else:
            assert w["spec"]["replicas"] == 1 and w["spec"]["strategy"]["type"] == "Recreate", name
        [container] = spec["containers"]
        ordinals = range(w["spec"]["replicas"]) if sts else None
        volumes = {v["name"]: v for v in spec["volumes"]}
        rig_mounts = [m for m in container["volumeMounts"] if m["mountPath"] == RIG_PATH]
        assert rig_mounts and volumes[rig_mounts[0]["name"]]["configMap"]["name"] == configmap
        assert rig_mounts[0]["subPath"] == "rig.toml"
        ports = {p["name"]: p["containerPort"] for p in container["ports"]}
        assert len(ports) == len(container["ports"]) == 2, f"{name}: one grpc and one metrics port"
        annotations = w["spec"]["template"]["metadata"].get("annotations", {})
        addresses = []
        for i, args in enumerate(_commands(container, ordinals)):
            parsed = parse_ig(args, f"k8s {name}")
            assert parsed.rig == RIG_PATH and parsed.bind == "0.0.0.0"
            assert_not_refused(rig, [parsed.bind])
            seen[parsed.command] += 1
            address = address_of(parsed, rig)
            addresses.append(address)
            assert ports["grpc"] == port_of(address), f"{name}: containerPort {ports} vs rig {address}"
            metrics = assert_scrapable(parsed, rig, f"k8s {name}")
            assert ports["metrics"] == metrics, f"{name}: containerPort {ports} vs metrics port {metrics}"
            # What deploy/prometheus/k8s.yml scrapes.
            assert annotations == {"prometheus.io/scrape": "true", "prometheus.io/port": str(metrics),
                                   "prometheus.io/path": "/metrics"}, f"{name}: annotations {annotations}"
            if sts:
                channels.append(channel_of(parsed, rig))
                assert address.rpartition(":")[0] == f"{name}-{i}.{w['spec']['serviceName']}.{ns}.svc"
        _probes(container, ports["grpc"], rig)
        # The Service the rig address names selects these pods, at the same port.
        host = addresses[0].rpartition(":")[0].split(".")
        svc_name = host[1] if sts else host[0]
        [svc] = [s for s in services if s["metadata"]["name"] == svc_name]
        assert svc["metadata"]["namespace"] == ns and host[-2:] == [ns, "svc"]
        assert _matches(svc["spec"]["selector"], labels)
        assert [(p["port"], p.get("targetPort", p["port"])) for p in svc["spec"]["ports"]] == \
            [(ports["grpc"], ports["grpc"])], f"Service {svc_name}"
        # A worker compiling its kernels is not ready, and must still be found by its name.
        assert svc["spec"].get("publishNotReadyAddresses") is True, f"Service {svc_name}"
        if rig.tls.enabled:
            files = _mounted_files(spec, container)
            missing = {rig.tls.ca, rig.tls.cert, rig.tls.key} - files
            assert not missing, f"{name}: nothing mounts {missing}"
        if sts:
            cpu = container["resources"]["requests"]["cpu"]
            assert cpu == container["resources"]["limits"]["cpu"] and str(cpu).isdigit(), "whole cores"
    assert seen == {"host": 1, "compositor": 1, "worker": len(rig.channels)}
    assert channels == list(rig.channel_names)


def test_k8s_prometheus_scrapes_the_annotated_pods_of_the_rig():
    namespaces = {d["metadata"]["namespace"] for d in _manifests() if d["kind"] in ("Deployment", "StatefulSet")}
    [job] = yaml.safe_load((PROMETHEUS / "k8s.yml").read_text())["scrape_configs"]
    [sd] = job["kubernetes_sd_configs"]
    assert sd["role"] == "pod" and set(sd["namespaces"]["names"]) == namespaces
    relabel = {tuple(r.get("source_labels", [])): r for r in job["relabel_configs"]}
    scrape = relabel[("__meta_kubernetes_pod_annotation_prometheus_io_scrape",)]
    assert (scrape["action"], scrape["regex"]) == ("keep", "true")
    address = relabel[("__meta_kubernetes_pod_ip", "__meta_kubernetes_pod_annotation_prometheus_io_port")]
    assert address["target_label"] == "__address__"
    assert re.fullmatch(address["regex"], "10.1.2.3;50261") and address["replacement"] == "$1:$2"
    path = relabel[("__meta_kubernetes_pod_annotation_prometheus_io_path",)]
    assert path["target_label"] == "__metrics_path__"


def test_kustomization_lists_every_manifest():
    kustomization = yaml.safe_load((K8S / "kustomization.yaml").read_text())
    listed = sorted(kustomization["resources"])
    assert listed == sorted(p.name for p in K8S.glob("*.yaml") if p.name != "kustomization.yaml")


def test_kubectl_accepts_the_manifests():
    kubectl = shutil.which("kubectl")
    if kubectl is None:
        pytest.skip("no kubectl")
    built = subprocess.run([kubectl, "kustomize", str(K8S)], capture_output=True, text=True, timeout=60)
    assert built.returncode == 0, built.stderr
    kinds = sorted(d["kind"] for d in yaml.safe_load_all(built.stdout) if d)
    assert kinds == sorted(d["kind"] for d in _manifests())
    applied = subprocess.run([kubectl, "apply", "--dry-run=client", "--validate=false", "--request-timeout=5s",
                              "-f", "-"], input=built.stdout, capture_output=True, text=True, timeout=120)
    if applied.returncode != 0 and re.search(r"connection refused|couldn't get current server API group|"
                                             r"unable to recognize|no configuration|dial tcp", applied.stderr):
        pytest.skip("kubectl apply --dry-run=client needs a cluster to discover its API kinds, and none is "
                    f"reachable ({applied.stderr.strip().splitlines()[-1][:160]}); kubectl kustomize passed")
    assert applied.returncode == 0, applied.stderr


# -- systemd ---------------------------------------------------------------------------------------

def _unit(path: Path) -> dict[str, list[tuple[str, str]]]:
    """A unit file's sections: [(key, value)] in order (a key may repeat)."""
    sections: dict[str, list[tuple[str, str]]] = {}
    current = None
    for line in path.read_text().replace("\\\n", " ").splitlines():
        line = line.strip()
        if not line or line[0] in "#;":
            continue
        if line.startswith("["):
            current = sections.setdefault(line.strip("[]"), [])
        else:
            assert current is not None, f"{path.name}: {line!r} outside a section"
            key, _, value = line.partition("=")
            current.append((key.strip(), value.strip()))
    return sections


def _values(unit: dict[str, list[tuple[str, str]]], key: str) -> list[str]:
    return [v for k, v in unit.get("Service", []) if k == key]


def test_systemd_units_match_the_rig():
    rig = load_rig(SYSTEMD_RIG)
    seen = set()
    for path in sorted(SYSTEMD.glob("*.service")):
        unit = _unit(path)
        assert "Install" in unit and "Unit" in unit, path.name
        template = path.stem.endswith("@")
        instances = list(rig.channel_names) if template else [None]
        execs = [v for key in ("ExecStartPre", "ExecStart") for v in _values(unit, key)]
        assert execs, path.name
        for instance in instances:
            for line in execs:
                argv = shlex.split(line.lstrip("-@+!:"))
                argv = [a.replace("%i", instance) if instance else a for a in argv]
                assert not any("%" in a for a in argv), f"{path.name}: {argv}"
                args = ig_args(argv)
                assert args is not None and argv[0] == "/opt/ig/.venv/bin/ig", f"{path.name}: {argv[0]}"
                parsed = parse_ig(args, path.name)
                assert parsed.rig == RIG_PATH
                seen.add(parsed.command)
                if parsed.command not in SERVICES:
                    continue
                assert parsed.bind == "0.0.0.0"
                assert_not_refused(rig, [parsed.bind])
                address_of(parsed, rig)  # the channel exists
                if parsed.command == "worker":
                    assert parsed.channel == instance
                assert _values(unit, "KillSignal") == ["SIGTERM"] and _values(unit, "Restart"), path.name
                if rig.tls.enabled:
                    # Each unit sees its own certificate at the rig file's one path.
                    binds = [b.lstrip("-").replace("%i", instance or "%i").split(":")
                             for b in _values(unit, "BindReadOnlyPaths")]
                    targets = {dst for _src, dst in binds}
                    assert {rig.tls.cert, rig.tls.key} <= targets, f"{path.name}: {targets}"
                    name = {"host": "host", "compositor": "compositor"}.get(parsed.command, instance)
                    assert {d: Path(s).name for s, d in binds} == {
                        rig.tls.cert: f"{name}.pem", rig.tls.key: f"{name}-key.pem"}, path.name
    assert set(SERVICES) <= seen


def test_readme_ports_table_is_the_default_rig():
    rig = load_rig(RIGS / "default.toml")
    text = (DEPLOY / "README.md").read_text()
    ports = {int(p) for p in re.findall(r"^\| [^|]+\| (\d+) \|", text, re.M)}
    expected = {port_of(a) for a in (rig.host_address, rig.compositor_address, *(c.address for c in rig.channels))}
    assert expected <= ports, f"deploy/README.md's ports table: {sorted(ports)} vs the default rig {sorted(expected)}"


def test_systemd_analyze_verifies_the_units(tmp_path):
    analyze = shutil.which("systemd-analyze")
    if analyze is None:
        pytest.skip("no systemd-analyze")
    ig = shutil.which("ig", path=str(Path(sys.executable).parent)) or shutil.which("ig")
    if ig is None:
        pytest.skip("no ig executable to stand for /opt/ig/.venv/bin/ig")
    units = []
    for path in sorted(SYSTEMD.glob("*.service")):
        name = path.name.replace("@.", "@left.")  # a template is verified as one of its instances
        (tmp_path / name).write_text(path.read_text().replace("/opt/ig/.venv/bin/ig", ig))
        units.append(str(tmp_path / name))
    result = subprocess.run([analyze, "verify", "--man=no", *units], capture_output=True, text=True, timeout=120)
    no_systemd = r"Failed to (connect|initialize)|System has not been booted"
    if result.returncode != 0 and re.search(no_systemd, result.stderr):
        pytest.skip(f"systemd-analyze cannot run here: {result.stderr.strip()[:160]}")
    assert result.returncode == 0 and "ig-" not in result.stderr, result.stderr


def test_every_flag_the_readme_names_is_an_option_of_ig():
    """A flag in backticks is one of the `ig` command the span names (`ig worker --bind`), or,
    standing alone, of some `ig` command: deploy/README.md once sent readers to check a worker's
    `--host`, which no command has."""
    subcommands = build_parser()._subparsers._group_actions[0].choices
    options = {name: {o for a in sub._actions for o in a.option_strings} for name, sub in subcommands.items()}
    checked, unknown = 0, []
    for span in re.findall(r"`([^`\n]+)`", (DEPLOY / "README.md").read_text()):
        flags = re.findall(r"(?<![\w-])--[a-z][a-z-]*", span)
        words = span.split()
        if not flags:
            continue
        if words[0] == "ig":
            owners = [words[1]]
        elif words[0].startswith("--"):
            owners = list(options)
        else:
            continue  # another program's flags: useradd, systemctl
        checked += len(flags)
        unknown += [f"{flag} (in `{span}`)" for flag in flags if not any(flag in options[c] for c in owners)]
    assert checked > 10  # the pattern still finds the README's flags
    assert not unknown, f"deploy/README.md names flags no ig command has: {unknown}"
