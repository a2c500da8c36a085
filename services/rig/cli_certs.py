"""`ig certs`: a test CA and one certificate per service of a rig (docs/security.md).

The certificates are made by services/rig/certs.py with the `cryptography` package, an optional
extra (`pip install 'ig-rig[tls]'`, or `make certs`); it is imported only when the command runs,
so that `ig --help` works without it.
"""

from __future__ import annotations

import argparse

from .cli_common import EXIT_BAD_INPUT, EXIT_FAILED, EXIT_OK, error, load_rig_or_report, whole_number

#: Validity when --days is not given (services/rig/certs.py DEFAULT_DAYS, repeated here so that
#: building the parser does not import cryptography).
_DEFAULT_DAYS = 365
_MAX_DAYS = 3650


def days(text: str) -> int:
    """argparse type: a validity, a whole number of days in [1, 3650]."""
    return whole_number(text, 1, _MAX_DAYS, "days")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of `ig certs`."""
    # Not add_rig_arguments: nothing here logs, so its --verbose would do nothing.
    parser.add_argument("--rig", default=None,
                        help="rig file whose services get certificates (docs/rig-format.md); default: the "
                             "bundled three-channel rig on 127.0.0.1")
    parser.add_argument("--out", default="certs",
                        help="output directory: ca.pem, ca-key.pem, and NAME.pem, NAME-key.pem for host, "
                             "compositor and each channel (default certs; keys are written mode 0600)")
    parser.add_argument("--days", type=days, default=_DEFAULT_DAYS,
                        help=f"validity of the CA and of every certificate, days (default {_DEFAULT_DAYS})")
    parser.add_argument("--force", action="store_true",
                        help="replace existing files (default: refuse, naming the first that exists)")
    parser.add_argument("--keep-ca", action="store_true",
                        help="sign with the CA already in --out instead of making a new one: new certificates "
                             "the machines still holding the old ones accept (rotation machine by machine)")


def run(args: argparse.Namespace) -> int:
    """Write the certificates and print the [tls] table; 0 ok, 1 a file could not be written,
    2 bad input (rig file, an existing file without --force, cryptography not installed)."""
    rig = load_rig_or_report(args.rig, "certs")
    if rig is None:
        return EXIT_BAD_INPUT
    try:
        from . import certs
    except ImportError as exc:
        error("certs", f"{exc}: ig certs needs the tls extra (pip install 'ig-rig[tls]', or make certs)")
        return EXIT_BAD_INPUT
    try:
        issued = certs.write_certs(rig, args.out, days=args.days, force=args.force, keep_ca=args.keep_ca)
    except (FileExistsError, ValueError) as exc:
        error("certs", exc)
        return EXIT_BAD_INPUT
    except OSError as exc:
        error("certs", f"{args.out}: cannot write: {exc}")
        return EXIT_FAILED
    for item in issued:
        sans = f"  (SAN {', '.join(item.sans)})" if item.sans else ""
        print(f"{item.name}: {item.cert}, {item.key}{sans}")
    print()
    print(certs.tls_table(issued, rig.source), end="")
    return EXIT_OK
