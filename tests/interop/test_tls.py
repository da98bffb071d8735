"""A stock gRPC client over TLS and mutual TLS: Python's grpcio with `ssl_channel_credentials`
(certificates made by `learner certs`) calls Status, the standard health service and server
reflection on the learner's one TLS listener, and is refused without the CA, without a client
certificate under mutual TLS, and in plaintext."""

import subprocess

import grpc
import pytest
from google.protobuf import descriptor_pool, message_factory
from grpc_reflection.v1alpha.proto_reflection_descriptor_database import ProtoReflectionDescriptorDatabase

from conftest import Learner, binary


def make_certs(out):
    subprocess.run([binary("learner"), "certs", "--out", str(out), "--hosts", "localhost,127.0.0.1"],
                   check=True, capture_output=True, timeout=60)
    return {name: (out / f"{name}.pem").read_bytes() for name in ["ca", "server", "server-key", "client", "client-key"]}


def reflected_call(channel, service, method, fields=None):
    """Calls SERVICE/METHOD with messages built from the reflected descriptors alone."""
    db = ProtoReflectionDescriptorDatabase(channel)
    assert service in db.get_services()
    pool = descriptor_pool.DescriptorPool(db)
    m = pool.FindServiceByName(service).methods_by_name[method]
    request_cls = message_factory.GetMessageClass(m.input_type)
    response_cls = message_factory.GetMessageClass(m.output_type)
    call = channel.unary_unary(f"/{service}/{method}", request_serializer=request_cls.SerializeToString,
                               response_deserializer=response_cls.FromString)
    return call(request_cls(**(fields or {})), timeout=10)


def health(channel):
    """grpc.health.v1 Check of the whole server, without reflection (the refusals come first)."""
    call = channel.unary_unary("/grpc.health.v1.Health/Check", request_serializer=lambda _: b"",
                               response_deserializer=lambda b: b)
    return call(None, timeout=10)


def refused(channel):
    with pytest.raises(grpc.RpcError) as e:
        health(channel)
    assert e.value.code() == grpc.StatusCode.UNAVAILABLE, e.value
    channel.close()


@pytest.mark.parametrize("mutual", [False, True])
def test_grpcio_over_tls_with_the_ca_and_refused_without(tmp_path, mutual):
    certs_dir = tmp_path / "certs"
    pem = make_certs(certs_dir)
    extra = ["--tls-cert", str(certs_dir / "server.pem"), "--tls-key", str(certs_dir / "server-key.pem")]
    if mutual:
        extra += ["--tls-client-ca", str(certs_dir / "ca.pem")]
    learner = Learner(tmp_path / "learner", extra=extra)
    try:
        host, port = learner.addr.rsplit(":", 1)
        target = f"localhost:{port}"
        identity = {"private_key": pem["client-key"], "certificate_chain": pem["client"]} if mutual else {}
        creds = grpc.ssl_channel_credentials(root_certificates=pem["ca"], **identity)
        with grpc.secure_channel(target, creds) as channel:
            # SERVING is 1: field 1, varint 1 (checked without generated code).
            assert health(channel) == b"\x08\x01"
            served = reflected_call(channel, "grpc.health.v1.Health", "Check", {"service": "hybriddrive.v1.Learner"})
            assert served.status == 1, served
            reply = reflected_call(channel, "hybriddrive.v1.Learner", "Status")
            assert reply.run_id.startswith("run-"), reply
            assert reply.variant == "hybrid", reply

        # Without the CA (the system's roots do not know it), in plaintext, and under mutual
        # TLS without a client certificate: no call goes through.
        refused(grpc.secure_channel(target, grpc.ssl_channel_credentials()))
        refused(grpc.insecure_channel(target))
        if mutual:
            refused(grpc.secure_channel(target, grpc.ssl_channel_credentials(root_certificates=pem["ca"])))
        # The learner's own client says which.
        no_ca = subprocess.run([binary("learner"), "health", "--addr", target], capture_output=True, text=True, timeout=60)
        assert no_ca.returncode != 0
        assert "it may serve TLS" in no_ca.stderr, no_ca.stderr
    finally:
        learner.stop()
