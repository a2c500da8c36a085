"""`ig status`: what a running host says about itself (GetHostStatus), as JSON.

For a rig following a CIGI host this is where an integrator looks first: the host's version
and byte order, the messages and packets used, refused and accepted-but-unused, the queries
answered, staleness and restarts (docs/cigi.md).
"""

from __future__ import annotations

import argparse
import json

from services.rig.cli_common import EXIT_FAILED, EXIT_OK, add_rig_arguments, error, load_rig_or_report, positive


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `ig status`."""
    add_rig_arguments(parser, bind=False)
    parser.add_argument("--timeout", type=positive, default=2.0, help="deadline of the request, seconds (default 2)")


def run(args: argparse.Namespace) -> int:
    """Print the host's status; 0 ok, 1 the host does not answer, 2 bad input."""
    import grpc
    from google.protobuf import json_format

    from ig.v1 import host_pb2, host_pb2_grpc
    from services.rig.cli_common import EXIT_BAD_INPUT, security_of
    from services.rig.grpc_util import make_channel

    rig = load_rig_or_report(args.rig, "status")
    if rig is None:
        return EXIT_BAD_INPUT
    try:
        security = security_of(rig)
    except ValueError as exc:
        error("status", exc)
        return EXIT_BAD_INPUT
    with make_channel(rig.host_address, security) as channel:
        try:
            status = host_pb2_grpc.HostServiceStub(channel).GetHostStatus(host_pb2.GetHostStatusRequest(),
                                                                          timeout=args.timeout)
        except grpc.RpcError as exc:
            error("status", f"host {rig.host_address}: {exc.code().name} {exc.details() or ''}".rstrip())
            return EXIT_FAILED
    print(json.dumps(json_format.MessageToDict(status, preserving_proto_field_name=True,
                                               always_print_fields_with_no_presence=True), indent=1))
    return EXIT_OK
