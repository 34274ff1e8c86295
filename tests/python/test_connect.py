"""Connecting: tokens, TLS, a server that is not there, the channel options."""

import shutil
import socket
import subprocess
import time

import grpc
import pytest

import fulcrum


def test_the_package_sets_its_channel_options():
    options = dict(fulcrum.CHANNEL_OPTIONS)
    assert options["grpc.http2.bdp_probe"] == 0
    assert 0 < options["grpc.http2.lookahead_bytes"] <= 64 * 1024
    assert options["grpc.max_receive_message_length"] == -1


def test_a_token_server_refuses_calls_without_it(make_server, tmp_path):
    token_file = tmp_path / "token"
    token_file.write_text("t0ken\n")
    secured = make_server("--token-file", token_file)
    with fulcrum.connect(secured.address) as anonymous:
        with pytest.raises(fulcrum.FulcrumError) as error:
            anonymous.worlds()
        assert error.value.code == grpc.StatusCode.UNAUTHENTICATED
    with fulcrum.connect(secured.address, token="wrong") as wrong:
        with pytest.raises(fulcrum.FulcrumError) as error:
            wrong.worlds()
        assert error.value.code == grpc.StatusCode.UNAUTHENTICATED
    with fulcrum.connect(secured.address, token="t0ken") as with_token:
        assert with_token.worlds() == []
    with fulcrum.connect(secured.address, token_file=token_file) as with_file:
        assert with_file.stats().worlds == 0
        # Frames stream with the token too.
        with with_file.create_world({"name": "x"}) as world:
            assert next(world.frames()).tick == 0


def test_no_server_is_unavailable():
    with socket.socket() as probe:  # a port nothing listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    start = time.monotonic()
    with pytest.raises(fulcrum.FulcrumError) as error:
        fulcrum.connect(f"127.0.0.1:{port}", wait=0.5)
    assert error.value.code == grpc.StatusCode.UNAVAILABLE
    assert time.monotonic() - start < 5
    with fulcrum.connect(f"127.0.0.1:{port}", timeout=5) as lazy:
        with pytest.raises(fulcrum.FulcrumError) as error:
            lazy.worlds()
        assert error.value.code == grpc.StatusCode.UNAVAILABLE


def test_bad_connect_arguments(tmp_path):
    with pytest.raises(fulcrum.FulcrumError) as error:
        fulcrum.connect("127.0.0.1:1", tls=tmp_path / "missing.pem")
    assert error.value.field == "tls" and "cannot read" in error.value.message
    (tmp_path / "not.pem").write_text("hello")
    with pytest.raises(fulcrum.FulcrumError) as error:
        fulcrum.connect("127.0.0.1:1", tls=tmp_path / "not.pem")
    assert "no PEM certificate" in error.value.message
    with pytest.raises(fulcrum.FulcrumError) as error:
        fulcrum.connect("127.0.0.1:1", tls_name="localhost")
    assert error.value.field == "tls_name"


@pytest.mark.skipif(shutil.which("openssl") is None,
                    reason="openssl missing (tools/setup.sh installs it)")
def test_tls_with_a_self_signed_certificate(make_server, tmp_path):
    key, cert = tmp_path / "key.pem", tmp_path / "cert.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt",
                    "ec_paramgen_curve:prime256v1", "-nodes", "-days", "2",
                    "-subj", "/CN=localhost",
                    "-addext", "subjectAltName=DNS:localhost,IP:127.0.0.1", "-keyout", str(key),
                    "-out", str(cert)], check=True, capture_output=True)
    secure = make_server("--tls-cert", cert, "--tls-key", key)
    with fulcrum.connect(secure.address, tls=cert) as client:
        assert client.worlds() == []
    port = secure.address.rsplit(":", 1)[1]
    with fulcrum.connect(f"localhost:{port}", tls=cert.read_bytes(), tls_name="localhost") \
            as client:
        assert client.stats().worlds == 0
    with fulcrum.connect(secure.address, timeout=3) as plaintext:
        with pytest.raises(fulcrum.FulcrumError) as error:
            plaintext.worlds()
        assert error.value.code == grpc.StatusCode.UNAVAILABLE
