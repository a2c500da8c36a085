"""The checked-in protobuf/gRPC code is exactly what protoc generates from proto/ig/v1."""

from pathlib import Path

import pytest

protoc = pytest.importorskip("grpc_tools.protoc", reason="grpcio-tools is a test dependency")

ROOT = Path(__file__).resolve().parent.parent
PROTO = ROOT / "proto"


def test_generated_code_is_current(tmp_path):
    sources = sorted(str(p.relative_to(PROTO)) for p in (PROTO / "ig" / "v1").glob("*.proto"))
    assert sources
    import grpc_tools
    include = str(Path(grpc_tools.__file__).parent / "_proto")
    rc = protoc.main(["protoc", f"-I{PROTO}", f"-I{include}", f"--python_out={tmp_path}",
                      f"--pyi_out={tmp_path}", f"--grpc_python_out={tmp_path}", *sources])
    assert rc == 0
    generated = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*.py*"))
    assert generated
    for rel in generated:
        checked_in = PROTO / rel
        assert checked_in.exists(), f"{rel} is generated but not checked in (run make proto)"
        assert checked_in.read_bytes() == (tmp_path / rel).read_bytes(), f"{rel} is stale (run make proto)"


def test_imports_read_as_ig_v1():
    from ig.v1 import compositor_pb2, frame_pb2, host_pb2_grpc  # noqa: F401
    assert frame_pb2.DESCRIPTOR.package == "ig.v1"
