#!/usr/bin/env python3
"""`ig-health`: the health check of a container running one `ig host|compositor|worker`.

Docker's HEALTHCHECK and Kubernetes' exec probes run it inside the service's container. It finds
the service's own command line (the first process running `ig host`, `ig compositor` or
`ig worker`), parses it with the real `ig` parser, looks the service's address up in the rig file
that command line names, and asks the standard gRPC health service (grpc.health.v1.Health,
service "") there: exit 0 when it answers SERVING, 1 otherwise (NOT_SERVING while a worker compiles
its kernels, or no answer).

It asks on the loopback at the service's port when the service listens on every interface
(`--bind 0.0.0.0`): a probe checks this container's process, never whatever a Service or DNS name
routes to. With the rig's [tls] it shows the rig's client certificate and checks the server's
certificate against the name of the service's rig address (docs/security.md). No argument; `ig-health
ig worker --rig R --channel left ...` checks the service that command line would start instead.

Kubernetes' own gRPC probes (`grpc: {port: N}`) speak plaintext without a client certificate, so
they cannot ask a service that requires mutual TLS: that is why this exists.
"""

from __future__ import annotations

import sys
from pathlib import Path

SERVICES = ("host", "compositor", "worker")


def service_argv(cmdlines: list[list[str]]) -> list[str]:
    """The `ig` arguments (from the subcommand on) of the first command line running a service.

    Raises:
        LookupError: none of them runs `ig host`, `ig compositor` or `ig worker`.
    """
    for argv in cmdlines:
        for i, arg in enumerate(argv[:-1]):
            if Path(arg).name == "ig" and argv[i + 1] in SERVICES:
                return argv[i + 1:]
    raise LookupError("no `ig host|compositor|worker` process found")


def probe_target(argv: list[str]) -> tuple[str, str, object]:
    """(address to ask, TLS server name, the rig's Security) for `ig` arguments argv.

    The address is the loopback at the service's port when it binds every interface, the
    interface it binds otherwise, and its rig address without --bind.

    Raises:
        SystemExit: argv is not a valid `ig` command line (argparse's exit code 2).
        ValueError: the rig file, the channel or a certificate cannot be used.
    """
    from services.cli import build_parser
    from services.rig.cli_common import security_of
    from services.rig.rigfile import load_rig, port_of

    args = build_parser(argv[0]).parse_args(argv)
    if args.rig is None:
        raise ValueError("the service runs without --rig")
    rig = load_rig(args.rig)
    if args.command == "host":
        address = rig.host_address
    elif args.command == "compositor":
        address = rig.compositor_address
    elif args.channel_index is not None:
        if not 0 <= args.channel_index < len(rig.channels):
            raise ValueError(f"--channel-index {args.channel_index}: the rig has {len(rig.channels)} channels")
        address = rig.channels[args.channel_index].address
    else:
        address = rig.channel(args.channel).address
    name = address.rpartition(":")[0]
    if args.bind is None:
        target = address
    elif args.bind in ("0.0.0.0", "::", "[::]"):
        target = f"127.0.0.1:{port_of(address)}"
    else:
        target = f"{args.bind}:{port_of(address)}"
    return target, name, security_of(rig)


def check(target: str, name: str, security, timeout_s: float = 3.0) -> str:
    """The health status name ("SERVING", ...) of the server at target."""
    import grpc
    from grpc_health.v1 import health_pb2, health_pb2_grpc

    from services.rig.grpc_util import check_health

    if not security.tls:
        return check_health(target, timeout_s=timeout_s, security=security)
    creds = grpc.ssl_channel_credentials(root_certificates=security.ca, private_key=security.key,
                                         certificate_chain=security.cert)
    with grpc.secure_channel(target, creds, options=[("grpc.ssl_target_name_override", name)]) as ch:
        resp = health_pb2_grpc.HealthStub(ch).Check(health_pb2.HealthCheckRequest(service=""), timeout=timeout_s)
        return health_pb2.HealthCheckResponse.ServingStatus.Name(resp.status)


def _cmdlines() -> list[list[str]]:
    """Every process's command line, lowest pid first."""
    out = []
    pids = sorted(int(p.name) for p in Path("/proc").iterdir() if p.name.isdigit())
    for pid in pids:
        try:
            raw = Path(f"/proc/{pid}/cmdline").read_bytes()
        except OSError:
            continue
        out.append([a.decode(errors="replace") for a in raw.split(b"\0") if a])
    return out


def main(argv: list[str]) -> int:
    import grpc

    try:
        args = argv if argv else service_argv(_cmdlines())
        target, name, security = probe_target(args[1:] if args[0] == "ig" else args)
        status = check(target, name, security)
    except grpc.RpcError as exc:
        print(f"ig-health: {exc.code().name}: {exc.details()}", file=sys.stderr)  # type: ignore[attr-defined]
        return 1
    except (LookupError, ValueError, OSError) as exc:
        print(f"ig-health: {exc}", file=sys.stderr)
        return 1
    print(f"ig-health: {target}: {status}")
    return 0 if status == "SERVING" else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
