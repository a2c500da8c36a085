"""Mutual TLS between the rig's services (docs/security.md): the certificates `ig certs` makes,
the [tls] table of the rig file, and what grpc_util's servers and channels accept and refuse.

The servers are in-process gRPC servers on a free loopback port serving the standard health
service (grpc_util.add_health), as every service of the rig does.
"""

from __future__ import annotations

import datetime
import ipaddress
import os
import stat
import tomllib

import grpc
import pytest
from cryptography import x509
from cryptography.x509.oid import ExtendedKeyUsageOID
from grpc_health.v1 import health_pb2, health_pb2_grpc

from services.cli import main
from services.rig.certs import write_certs
from services.rig.cli_common import security_of
from services.rig.grpc_util import (
    PlaintextRefused,
    Security,
    add_health,
    bind,
    check_health,
    is_loopback,
    make_channel,
    make_server,
)
from services.rig.rigfile import RigError, load_rig, parse_rig, rig_toml

#: A rig whose services are on an IP literal, a DNS name, a 10.x address and an IPv6 literal.
RIG_TOML = """
[host]
address = "127.0.0.1:50150"

[compositor]
address = "ig-compositor.local:50151"

[[channels]]
name = "left"
address = "10.1.2.3:50161"
left_deg = -30.0
right_deg = 30.0
bottom_deg = -22.5
top_deg = 22.5
width = 64
height = 48

[[channels]]
name = "right"
address = "[fd00::13]:50163"
left_deg = -30.0
right_deg = 30.0
bottom_deg = -22.5
top_deg = 22.5
width = 64
height = 48
"""

#: Short: a refused handshake fails at once; a deadline only bounds a test that would hang.
TIMEOUT_S = 5.0


@pytest.fixture(scope="module")
def pki(tmp_path_factory):
    """The rig file, its certificates, and a second CA's certificates (a stranger's)."""
    tmp = tmp_path_factory.mktemp("pki")
    rig_path = tmp / "rig.toml"
    rig_path.write_text(RIG_TOML)
    rig = load_rig(rig_path)
    issued = {i.name: i for i in write_certs(rig, tmp / "certs", days=30)}
    other = {i.name: i for i in write_certs(rig, tmp / "other", days=30)}
    return {"tmp": tmp, "rig_path": rig_path, "rig": rig, "issued": issued, "other": other}


def security(issued, name, ca_from=None) -> Security:
    """The Security of service name: its certificate and key, trusting ca_from's CA (its own)."""
    ca = (ca_from or issued)["ca"].cert
    return Security.from_files(str(ca), str(issued[name].cert), str(issued[name].key))


@pytest.fixture
def tls_server(pki):
    """A health server with the host's certificate on a free loopback port; its address."""
    server = make_server()
    add_health(server, ["ig.v1.HostService"])
    port = bind(server, "127.0.0.1:0", security(pki["issued"], "host"))
    server.start()
    yield f"127.0.0.1:{port}"
    server.stop(None)


def refusal(address, credentials, options=()):
    """The status code of a health check over a channel with these credentials (None: plaintext)."""
    channel = (grpc.secure_channel(address, credentials, options=list(options)) if credentials
               else grpc.insecure_channel(address))
    with channel:
        try:
            health_pb2_grpc.HealthStub(channel).Check(health_pb2.HealthCheckRequest(), timeout=TIMEOUT_S)
        except grpc.RpcError as exc:
            return exc.code()
    return grpc.StatusCode.OK


def test_a_client_with_a_certificate_of_the_rigs_ca_is_served(pki, tls_server):
    for name in ("left", "compositor", "host"):
        assert check_health(tls_server, security=security(pki["issued"], name), timeout_s=TIMEOUT_S) == "SERVING"
    # The server's certificate names localhost too: services on one machine dial either.
    port = tls_server.rpartition(":")[2]
    assert check_health(f"localhost:{port}", security=security(pki["issued"], "left"),
                        timeout_s=TIMEOUT_S) == "SERVING"


def test_clients_without_a_certificate_of_the_rigs_ca_are_refused_and_the_server_serves_on(pki, tls_server):
    issued, other = pki["issued"], pki["other"]
    ca = issued["ca"].cert.read_bytes()
    cases = {
        # Plaintext to a TLS port: no handshake at all.
        "plaintext": None,
        # TLS that trusts the server but shows no certificate: require_client_auth refuses it.
        "no certificate": grpc.ssl_channel_credentials(root_certificates=ca),
        # A certificate and key of another CA, trusting the rig's CA: the server refuses it.
        "another CA's certificate": grpc.ssl_channel_credentials(
            root_certificates=ca, private_key=other["left"].key.read_bytes(),
            certificate_chain=other["left"].cert.read_bytes()),
        # A good certificate, trusting only the other CA: the client refuses the server.
        "trusting another CA": grpc.ssl_channel_credentials(
            root_certificates=other["ca"].cert.read_bytes(), private_key=issued["left"].key.read_bytes(),
            certificate_chain=issued["left"].cert.read_bytes()),
    }
    codes = {what: refusal(tls_server, creds) for what, creds in cases.items()}
    assert codes == dict.fromkeys(cases, grpc.StatusCode.UNAVAILABLE)
    # The refusals cost the server nothing: the rig's own client is served afterwards.
    assert check_health(tls_server, security=security(issued, "left"), timeout_s=TIMEOUT_S) == "SERVING"


def test_a_client_dialling_a_name_the_server_certificate_lacks_refuses_it(pki, tls_server):
    # The host's certificate names 127.0.0.1, localhost and nothing else: the SANs are what stops
    # one rig machine's certificate standing in for another's address.
    issued = pki["issued"]
    creds = grpc.ssl_channel_credentials(root_certificates=issued["ca"].cert.read_bytes(),
                                         private_key=issued["left"].key.read_bytes(),
                                         certificate_chain=issued["left"].cert.read_bytes())
    assert refusal(tls_server, creds, [("grpc.ssl_target_name_override", "10.1.2.3")]) == grpc.StatusCode.UNAVAILABLE


def test_security_of_the_rig_reads_its_tls_table(pki):
    rig_path = pki["tmp"] / "rig-tls.toml"
    rig_path.write_text(RIG_TOML + '\n[tls]\nca = "certs/ca.pem"\n'
                                   'cert = "certs/left.pem"\nkey = "certs/left-key.pem"\n')
    sec = security_of(load_rig(rig_path))
    assert sec.tls and not sec.allow_plaintext
    assert sec.cert == pki["issued"]["left"].cert.read_bytes()
    assert sec.key == pki["issued"]["left"].key.read_bytes()


# --- plaintext ---------------------------------------------------------------------------------


@pytest.mark.parametrize("address,loopback", [
    ("127.0.0.1:1", True), ("127.1.2.3:1", True), ("localhost:1", True), ("[::1]:1", True),
    ("0.0.0.0:1", False), ("10.0.0.12:1", False), ("[::]:1", False), ("ig-host.local:1", False)])
def test_is_loopback(address, loopback):
    assert is_loopback(address) is loopback


@pytest.mark.parametrize("address", ["0.0.0.0:0", "10.0.0.10:0", "[::]:0"])
def test_plaintext_bind_off_the_loopback_is_refused(address):
    server = make_server()
    with pytest.raises(PlaintextRefused, match=r"listening on .*plaintext is refused off the loopback"):
        bind(server, address, Security())
    with pytest.raises(PlaintextRefused):
        bind(server, address)  # no security at all: plaintext


@pytest.mark.parametrize("address", ["0.0.0.0:50150", "10.0.0.10:50150", "ig-host.local:50150"])
def test_plaintext_connect_off_the_loopback_is_refused_unless_allowed(address):
    assert issubclass(PlaintextRefused, OSError)  # callers reporting OSError report it too
    with pytest.raises(PlaintextRefused, match=rf"connecting to {address}: plaintext is refused"):
        make_channel(address, Security())
    with pytest.raises(PlaintextRefused):
        check_health(address, timeout_s=0.1)
    make_channel(address, Security(allow_plaintext=True)).close()  # channels connect lazily


def test_plaintext_bind_to_every_interface_when_allowed():
    server = make_server()
    add_health(server, [])
    port = bind(server, "0.0.0.0:0", Security(allow_plaintext=True))
    server.start()
    try:
        assert check_health(f"127.0.0.1:{port}", timeout_s=TIMEOUT_S) == "SERVING"
    finally:
        server.stop(None)


def test_plaintext_on_the_loopback_works():
    server = make_server()
    add_health(server, [])
    port = bind(server, "127.0.0.1:0")
    server.start()
    try:
        assert check_health(f"127.0.0.1:{port}", timeout_s=TIMEOUT_S) == "SERVING"
        assert check_health(f"localhost:{port}", security=Security(), timeout_s=TIMEOUT_S) == "SERVING"
    finally:
        server.stop(None)


# --- Security.from_files ------------------------------------------------------------------------


def test_from_files_with_no_files_is_plaintext():
    assert Security.from_files("", "", "") == Security()
    assert Security.from_files("", "", "", allow_plaintext=True) == Security(allow_plaintext=True)


def test_from_files_names_a_missing_file(pki, tmp_path):
    issued = pki["issued"]
    missing = tmp_path / "nope.pem"
    with pytest.raises(ValueError, match=rf"tls\.cert: '{missing}': cannot read"):
        Security.from_files(str(issued["ca"].cert), str(missing), str(issued["left"].key))


def test_from_files_names_a_file_that_is_not_pem(pki, tmp_path):
    issued = pki["issued"]
    der = tmp_path / "key.der"
    der.write_bytes(b"\x30\x82\x01\x0a not a pem file")
    with pytest.raises(ValueError, match=rf"tls\.key: '{der}' is not a PEM file"):
        Security.from_files(str(issued["ca"].cert), str(issued["left"].cert), str(der))


def test_from_files_needs_all_three(pki):
    with pytest.raises(ValueError, match=r"tls\.cert: missing"):
        Security.from_files(str(pki["issued"]["ca"].cert), "", "")


# --- the [tls] table of the rig file ------------------------------------------------------------


def rig_doc(tls):
    return {**tomllib.loads(RIG_TOML), "tls": tls}


def test_relative_paths_are_taken_from_the_rig_files_directory(tmp_path):
    rig_dir = tmp_path / "etc"
    rig_dir.mkdir()
    path = rig_dir / "rig.toml"
    path.write_text(RIG_TOML + '\n[tls]\nca = "certs/ca.pem"\ncert = "/abs/left.pem"\nkey = "../left-key.pem"\n'
                               "allow_plaintext = true\n")
    tls = load_rig(path).tls
    assert tls.ca == str(rig_dir / "certs" / "ca.pem")
    assert tls.cert == "/abs/left.pem"
    assert tls.key == str(rig_dir / ".." / "left-key.pem")
    assert tls.allow_plaintext and tls.enabled


def test_no_tls_table_is_plaintext():
    tls = parse_rig(tomllib.loads(RIG_TOML)).tls
    assert not tls.enabled and not tls.allow_plaintext


def test_tls_table_round_trips(tmp_path):
    rig = parse_rig(rig_doc({"ca": "/c/ca.pem", "cert": "/c/l.pem", "key": "/c/l-key.pem", "allow_plaintext": True}))
    assert parse_rig(tomllib.loads(rig_toml(rig))).tls == rig.tls


@pytest.mark.parametrize("tls,pattern", [
    ({"ca": "ca.pem", "cert": "left.pem"}, r"tls: key missing: mutual TLS needs ca, cert and key together"),
    ({"cert": "left.pem"}, r"tls: ca, key missing"),
    ({"ca": "ca.pem", "cert": "left.pem", "key": ""}, r"tls\.key: '' is not a file path"),
    ({"ca": "ca.pem", "cert": "left.pem", "key": 3}, r"tls\.key: 3 is not a file path"),
    ({"allow_plaintext": "yes"}, r"tls\.allow_plaintext: 'yes' is not true or false"),
    ({"certificate": "left.pem"}, r"tls\.certificate: unknown key"),
    ("certs", r"tls: 'certs' is not a table"),
])
def test_a_bad_tls_table_is_refused_naming_the_key(tls, pattern):
    with pytest.raises(RigError, match=pattern):
        parse_rig(rig_doc(tls))


# --- ig certs -----------------------------------------------------------------------------------


def certificate(path):
    return x509.load_pem_x509_certificate(path.read_bytes())


def sans(path):
    ext = certificate(path).extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    return set(ext.get_values_for_type(x509.IPAddress)), set(ext.get_values_for_type(x509.DNSName))


def test_every_certificate_names_its_rig_host_and_the_loopback(pki):
    issued = pki["issued"]
    loopback = ipaddress.ip_address("127.0.0.1")
    expected = {"host": ({loopback}, {"localhost"}),
                "compositor": ({loopback}, {"ig-compositor.local", "localhost"}),
                "left": ({ipaddress.ip_address("10.1.2.3"), loopback}, {"localhost"}),
                "right": ({ipaddress.ip_address("fd00::13"), loopback}, {"localhost"})}
    assert {name: sans(issued[name].cert) for name in expected} == expected


def test_certificates_are_server_and_client_certificates_signed_by_the_ca(pki):
    ca = certificate(pki["issued"]["ca"].cert)
    assert ca.extensions.get_extension_for_class(x509.BasicConstraints).value.ca
    for name in ("host", "compositor", "left", "right"):
        cert = certificate(pki["issued"][name].cert)
        cert.verify_directly_issued_by(ca)
        eku = cert.extensions.get_extension_for_class(x509.ExtendedKeyUsage).value
        assert set(eku) == {ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH}
        assert not cert.extensions.get_extension_for_class(x509.BasicConstraints).value.ca
        lifetime = cert.not_valid_after_utc - cert.not_valid_before_utc
        assert lifetime == datetime.timedelta(days=30, minutes=5)  # backdated for clock skew


def run_certs(capsys, *argv):
    code = main(["certs", *argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_ig_certs_writes_keys_0600_and_prints_the_tls_table(pki, tmp_path, capsys):
    rig_path = tmp_path / "rig.toml"
    rig_path.write_text(RIG_TOML)
    code, out, _ = run_certs(capsys, "--rig", str(rig_path), "--out", str(tmp_path / "certs"), "--days", "10")
    assert code == 0
    names = ["ca", "host", "compositor", "left", "right"]
    assert sorted(p.name for p in (tmp_path / "certs").iterdir()) == sorted(
        [f"{n}.pem" for n in names] + [f"{n}-key.pem" for n in names])
    for name in names:
        assert stat.S_IMODE(os.stat(tmp_path / "certs" / f"{name}-key.pem").st_mode) == 0o600
        assert stat.S_IMODE(os.stat(tmp_path / "certs" / f"{name}.pem").st_mode) == 0o644
    assert stat.S_IMODE(os.stat(tmp_path / "certs").st_mode) == 0o700
    # The printed table, pasted into the rig file as it is, gives the host mutual TLS (paths
    # relative to the rig file, the certificates being below it).
    table = out[out.index("[tls]"):]
    assert 'ca = "certs/ca.pem"' in table
    rig_path.write_text(RIG_TOML + "\n" + out[out.index("# Paste"):])
    sec = security_of(load_rig(rig_path))
    assert sec.tls and sec.cert == (tmp_path / "certs" / "host.pem").read_bytes()


def test_ig_certs_twice_refuses_to_overwrite_unless_forced(tmp_path, capsys):
    rig_path = tmp_path / "rig.toml"
    rig_path.write_text(RIG_TOML)
    out = tmp_path / "certs"
    argv = ["--rig", str(rig_path), "--out", str(out)]
    assert run_certs(capsys, *argv)[0] == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    code, _, err = run_certs(capsys, *argv)
    assert code == 2
    assert f"ig certs: error: {out / 'ca.pem'}: exists; not overwritten (--force replaces it)" in err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # nothing written
    # A key whose mode was loosened is 0600 again once replaced.
    (out / "left-key.pem").chmod(0o644)
    assert run_certs(capsys, *argv, "--force")[0] == 0
    assert stat.S_IMODE(os.stat(out / "left-key.pem").st_mode) == 0o600
    assert (out / "ca.pem").read_bytes() != before["ca.pem"]


def test_ig_certs_keep_ca_signs_new_certificates_with_the_ca_already_there(tmp_path, capsys):
    rig_path = tmp_path / "rig.toml"
    rig_path.write_text(RIG_TOML)
    out = tmp_path / "certs"
    argv = ["--rig", str(rig_path), "--out", str(out)]
    assert run_certs(capsys, *argv)[0] == 0
    ca, left = (out / "ca.pem").read_bytes(), (out / "left.pem").read_bytes()
    code, _, err = run_certs(capsys, *argv, "--keep-ca")
    assert code == 2 and f"{out / 'host.pem'}: exists" in err  # the CA is read, the rest still refused
    assert run_certs(capsys, *argv, "--keep-ca", "--force")[0] == 0
    assert (out / "ca.pem").read_bytes() == ca and (out / "left.pem").read_bytes() != left
    certificate(out / "left.pem").verify_directly_issued_by(certificate(out / "ca.pem"))


def test_ig_certs_keep_ca_without_a_ca_names_the_file(tmp_path, capsys):
    rig_path = tmp_path / "rig.toml"
    rig_path.write_text(RIG_TOML)
    code, _, err = run_certs(capsys, "--rig", str(rig_path), "--out", str(tmp_path / "certs"), "--keep-ca")
    assert code == 2 and f"{tmp_path / 'certs' / 'ca.pem'}: cannot read" in err


@pytest.mark.parametrize("name,stem", [("host", "host"), ("ca-key", "ca-key"), ("compositor-key", "compositor-key")])
def test_ig_certs_refuses_a_channel_whose_files_would_collide(tmp_path, capsys, name, stem):
    rig_path = tmp_path / "rig.toml"
    rig_path.write_text(RIG_TOML.replace('name = "left"', f'name = "{name}"'))
    code, _, err = run_certs(capsys, "--rig", str(rig_path), "--out", str(tmp_path / "certs"))
    assert code == 2
    assert f"channels[0].name: {name!r} would write {stem}.pem" in err
    assert not (tmp_path / "certs").exists()


@pytest.mark.parametrize("days", ["0", "3651", "ten"])
def test_ig_certs_bad_days_exit_2(tmp_path, capsys, days):
    with pytest.raises(SystemExit) as exc:
        main(["certs", "--out", str(tmp_path / "certs"), "--days", days])
    assert exc.value.code == 2
    assert days in capsys.readouterr().err
