"""A test certificate authority and one certificate per service of a rig (docs/security.md).

`ig certs` (services/rig/cli_certs.py) calls write_certs. The layout of the output directory:

    ca.pem, ca-key.pem               the rig's CA (the key 0600; it signs, no service reads it)
    host.pem, host-key.pem           the host's certificate and key (0600)
    compositor.pem, compositor-key.pem
    <channel>.pem, <channel>-key.pem one pair per channel of the rig

Every service certificate is both a server and a client certificate (serverAuth and clientAuth):
a service listens with it and shows it when it connects to the others. Its subjectAltName holds
the host of the service's rig address (an IP SAN for an IP literal, a DNS SAN for a name) plus
localhost and 127.0.0.1, because gRPC checks the name a client dialled against the server's SANs.
Keys are EC P-256: small, fast handshakes, and supported by every gRPC TLS stack.
"""

from __future__ import annotations

import datetime
import ipaddress
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from .rigfile import Rig

#: Validity of the CA and of every certificate when not told otherwise, days.
DEFAULT_DAYS = 365

#: Longest validity accepted, days (ten years: a test CA is meant to be rotated).
MAX_DAYS = 3650

#: Certificates start this long before they are made, so that a machine whose clock is a little
#: behind the one that made them still accepts them.
_BACKDATE = datetime.timedelta(minutes=5)

#: Names every certificate answers to besides its rig host: services on one machine reach each
#: other through the loopback.
_LOOPBACK_NAMES = ("localhost", "127.0.0.1")


@dataclass(frozen=True)
class Issued:
    """One certificate written by write_certs.

    Attributes:
        name: the service it belongs to: "host", "compositor" or a channel name ("ca" for the CA).
        cert: path of its PEM certificate.
        key: path of its PEM private key (mode 0600).
        sans: its subjectAltName entries as text ("127.0.0.1", "ig-host.local"); empty for the CA.
    """

    name: str
    cert: Path
    key: Path
    sans: tuple[str, ...] = ()


def host_of(address: str) -> str:
    """The host of a host:port address, without the brackets of an IPv6 literal."""
    return address.rpartition(":")[0].strip("[]")


def rig_services(rig: Rig) -> dict[str, str]:
    """Each service of the rig that gets a certificate, by name, with the host of its address.

    Raises:
        ValueError: a channel whose name would give two certificates the same file (a channel
            called "host", "ca" or "compositor-key"); the message names the channel.
    """
    services = {"host": host_of(rig.host_address), "compositor": host_of(rig.compositor_address)}
    # Every file the layout holds, so that no two names write one file ("ca-key" -> ca-key.pem).
    files = {"ca": "the CA", "ca-key": "the CA's key", "host-key": "the host's key",
             "compositor-key": "the compositor's key", "host": "the host", "compositor": "the compositor"}
    for i, ch in enumerate(rig.channels):
        for stem in (ch.name, f"{ch.name}-key"):
            if stem in files:
                raise ValueError(f"channels[{i}].name: {ch.name!r} would write {stem}.pem, the file of "
                                 f"{files[stem]}; rename the channel")
            files[stem] = f"channel {ch.name!r}"
        services[ch.name] = host_of(ch.address)
    return services


def subject_alt_names(hosts: Iterable[str]) -> list[x509.GeneralName]:
    """The subjectAltName entries for hosts plus localhost and 127.0.0.1, without repeats: an IP
    address entry for an IP literal (IPv4 or IPv6), a DNS name entry otherwise."""
    names: list[x509.GeneralName] = []
    for host in (*hosts, *_LOOPBACK_NAMES):
        try:
            entry: x509.GeneralName = x509.IPAddress(ipaddress.ip_address(host))
        except ValueError:
            entry = x509.DNSName(host)
        if entry not in names:
            names.append(entry)
    return names


def make_ca(*, days: int = DEFAULT_DAYS, common_name: str = "ig rig test CA",
            now: datetime.datetime | None = None) -> tuple[x509.Certificate, ec.EllipticCurvePrivateKey]:
    """A self-signed CA certificate and its key, valid for days from now, that may sign service
    certificates only (path length 0)."""
    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, common_name)])
    start = (now or datetime.datetime.now(datetime.UTC)) - _BACKDATE
    cert = (
        x509.CertificateBuilder()
        .subject_name(name).issuer_name(name).public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(start).not_valid_after(start + _BACKDATE + datetime.timedelta(days=days))
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(x509.KeyUsage(digital_signature=False, content_commitment=False, key_encipherment=False,
                                     data_encipherment=False, key_agreement=False, key_cert_sign=True,
                                     crl_sign=True, encipher_only=False, decipher_only=False), critical=True)
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
        .sign(key, hashes.SHA256())
    )
    return cert, key


def issue(ca_cert: x509.Certificate, ca_key: ec.EllipticCurvePrivateKey, name: str, hosts: Iterable[str], *,
          days: int = DEFAULT_DAYS,
          now: datetime.datetime | None = None) -> tuple[x509.Certificate, ec.EllipticCurvePrivateKey]:
    """A certificate for the service called name, signed by the CA, usable as server and client
    certificate, whose subjectAltName covers hosts (see subject_alt_names); valid for days."""
    key = ec.generate_private_key(ec.SECP256R1())
    start = (now or datetime.datetime.now(datetime.UTC)) - _BACKDATE
    ca_ski = ca_cert.extensions.get_extension_for_class(x509.SubjectKeyIdentifier).value
    cert = (
        x509.CertificateBuilder()
        .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, f"ig {name}")]))
        .issuer_name(ca_cert.subject).public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(start).not_valid_after(start + _BACKDATE + datetime.timedelta(days=days))
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(x509.KeyUsage(digital_signature=True, content_commitment=False, key_encipherment=False,
                                     data_encipherment=False, key_agreement=True, key_cert_sign=False,
                                     crl_sign=False, encipher_only=False, decipher_only=False), critical=True)
        .add_extension(x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH]),
                       critical=False)
        .add_extension(x509.SubjectAlternativeName(subject_alt_names(hosts)), critical=False)
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), critical=False)
        .add_extension(x509.AuthorityKeyIdentifier.from_issuer_subject_key_identifier(ca_ski), critical=False)
        .sign(ca_key, hashes.SHA256())
    )
    return cert, key


def write_certs(rig: Rig, out: str | Path, *, days: int = DEFAULT_DAYS, force: bool = False,
                keep_ca: bool = False) -> list[Issued]:
    """Make the rig's CA and one certificate per service (host, compositor, each channel) in out.

    Nothing is written unless every file can be: an existing file is an error unless force.

    Args:
        rig: the rig whose services get certificates (their addresses give the SANs).
        out: the output directory, created (mode 0700) if missing.
        days: validity of every certificate (and of a new CA), days, in [1, MAX_DAYS].
        force: replace existing files.
        keep_ca: sign with the CA already in out (ca.pem, ca-key.pem) instead of making one: new
            service certificates that the machines still holding the old ones keep accepting.

    Returns:
        The CA first, then host, compositor and the channels in the rig's order.

    Raises:
        FileExistsError: a file to write exists and not force; the message names it.
        ValueError: days out of range, a channel name that collides with another file, or (with
            keep_ca) a CA file that is missing or not a PEM certificate / EC key; the message names it.
        OSError: a file cannot be written.
    """
    if isinstance(days, bool) or not isinstance(days, int) or not 1 <= days <= MAX_DAYS:
        raise ValueError(f"days: {days!r} is not a whole number of days in [1, {MAX_DAYS}]")
    out = Path(out)
    services = rig_services(rig)
    ca_pem, ca_key_pem = out / "ca.pem", out / "ca-key.pem"
    targets = [] if keep_ca else [ca_pem, ca_key_pem]
    for name in services:
        targets += [out / f"{name}.pem", out / f"{name}-key.pem"]
    if not force:
        for path in targets:
            if path.exists():
                raise FileExistsError(f"{path}: exists; not overwritten (--force replaces it)")
    if keep_ca:
        ca_cert, ca_key = load_ca(ca_pem, ca_key_pem)
    else:
        ca_cert, ca_key = make_ca(days=days)
    out.mkdir(mode=0o700, parents=True, exist_ok=True)
    issued = [Issued("ca", ca_pem, ca_key_pem)]
    if not keep_ca:
        _write(ca_pem, ca_cert.public_bytes(serialization.Encoding.PEM), 0o644, force)
        _write(ca_key_pem, _key_bytes(ca_key), 0o600, force)
    for name, host in services.items():
        cert, key = issue(ca_cert, ca_key, name, [host], days=days)
        cert_path, key_path = out / f"{name}.pem", out / f"{name}-key.pem"
        _write(key_path, _key_bytes(key), 0o600, force)
        _write(cert_path, cert.public_bytes(serialization.Encoding.PEM), 0o644, force)
        sans = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
        issued.append(Issued(name, cert_path, key_path, tuple(str(entry.value) for entry in sans)))
    return issued


def load_ca(cert_path: Path, key_path: Path) -> tuple[x509.Certificate, ec.EllipticCurvePrivateKey]:
    """The CA certificate and EC key of an earlier write_certs.

    Raises:
        ValueError: a file missing, unreadable, not PEM or not of the right kind; the message names it.
    """
    data = {}
    for path in (cert_path, key_path):
        try:
            data[path] = path.read_bytes()
        except OSError as exc:
            raise ValueError(f"{path}: cannot read: {exc.strerror or exc}") from None
    try:
        cert = x509.load_pem_x509_certificate(data[cert_path])
    except ValueError:
        raise ValueError(f"{cert_path}: not a PEM certificate") from None
    try:
        key = serialization.load_pem_private_key(data[key_path], password=None)
    except (ValueError, TypeError):
        raise ValueError(f"{key_path}: not an unencrypted PEM private key") from None
    if not isinstance(key, ec.EllipticCurvePrivateKey):
        raise ValueError(f"{key_path}: a {type(key).__name__}, not the EC key ig certs makes")
    if key.public_key() != cert.public_key():
        raise ValueError(f"{key_path}: not the key of {cert_path}")
    return cert, key


def tls_table(issued: list[Issued], rig_source: str) -> str:
    """The [tls] table to paste into the rig file, naming the host's certificate, with a comment
    saying which file each other machine names instead.

    Paths are relative to the rig file's directory when the certificates are below it (the rig
    file takes relative paths from there), absolute otherwise.
    """
    base = Path(rig_source).resolve().parent if rig_source else None

    def shown(path: Path) -> str:
        full = path.resolve()
        if base is not None and full.is_relative_to(base):
            return full.relative_to(base).as_posix()
        return full.as_posix()

    ca, host = issued[0], next(i for i in issued if i.name == "host")
    width = max(len(i.name) for i in issued)
    machines = "".join(f"#   {i.name:<{width}}  {i.cert.name}, {i.key.name}\n" for i in issued if i.name != "ca")
    return (f"# Paste into the rig file of each machine, naming that machine's own certificate and key\n"
            f"# (below, the host's):\n{machines}"
            f"# Keep {ca.key.name} off the rig's machines: it signs certificates, no service reads it.\n"
            f"[tls]\n"
            f'ca = "{shown(ca.cert)}"\n'
            f'cert = "{shown(host.cert)}"\n'
            f'key = "{shown(host.key)}"\n')


def _key_bytes(key: ec.EllipticCurvePrivateKey) -> bytes:
    # Unencrypted: services read their keys unattended; the file's mode keeps other users out.
    return key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                             serialization.NoEncryption())


def _write(path: Path, data: bytes, mode: int, force: bool) -> None:
    # The file is created with its mode (a key is never readable by others, not even for a
    # moment); O_EXCL makes a file that appeared since the check an error, not a victim.
    flags = os.O_WRONLY | os.O_CREAT | (os.O_TRUNC if force else os.O_EXCL)
    fd = os.open(path, flags, mode)
    with os.fdopen(fd, "wb") as f:
        os.fchmod(f.fileno(), mode)  # an existing file replaced with force keeps its old mode otherwise
        f.write(data)
