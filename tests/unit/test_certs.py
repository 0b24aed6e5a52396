"""`cbgo certs make`: the authority, one certificate per name, private keys 0600.

These run the real `openssl` (the tool's only dependency) and read its output back with it;
a TLS handshake with the certificates is tested in tests/integration/test_tls.py.
"""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from cbgo.cli.certs import (
    DEFAULT_HOSTS,
    CertError,
    check_name,
    default_names,
    make,
    subject_alt_names,
)
from cbgo.registry import SERVICES

pytestmark = pytest.mark.skipif(shutil.which("openssl") is None, reason="needs openssl")


def openssl(*args: str) -> str:
    return subprocess.run(["openssl", *args], capture_output=True, text=True,
                          check=True).stdout


def x509_text(cert: Path) -> str:
    return openssl("x509", "-in", str(cert), "-noout", "-text")


def mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def quiet(_line: str) -> None:
    pass


def test_the_default_names_are_the_router_every_service_and_the_operator():
    names = default_names()
    assert names[0] == "router"
    assert {s.name for s in SERVICES} | {"operator"} <= set(names)
    assert len(names) == len(set(names))


def test_subject_alt_names_tell_ip_addresses_from_host_names():
    assert subject_alt_names(["router", "127.0.0.1", "::1", "robot-pc.local"]) == (
        "DNS:router, IP:127.0.0.1, IP:::1, DNS:robot-pc.local")


def test_make_writes_the_authority_and_a_directory_per_name(tmp_path):
    issued = make(tmp_path, ["router", "planner"], list(DEFAULT_HOSTS), report=quiet)
    assert issued == ["router", "planner"]
    assert sorted(p.name for p in (tmp_path / "ca").iterdir()) == ["ca.key", "ca.pem"]
    authority = (tmp_path / "ca" / "ca.pem").read_bytes()
    for name in ("router", "planner"):
        assert sorted(p.name for p in (tmp_path / name).iterdir()) == [
            "ca.pem", "cert.pem", "key.pem"]
        assert (tmp_path / name / "ca.pem").read_bytes() == authority
        verified = openssl("verify", "-CAfile", str(tmp_path / "ca" / "ca.pem"),
                           str(tmp_path / name / "cert.pem"))
        assert verified.strip().endswith("OK")


def test_private_keys_are_owner_only_even_under_a_permissive_umask(tmp_path):
    old = os.umask(0)
    try:
        make(tmp_path, ["planner"], list(DEFAULT_HOSTS), report=quiet)
    finally:
        os.umask(old)
    assert mode(tmp_path / "ca" / "ca.key") == 0o600
    assert mode(tmp_path / "ca") == 0o700
    assert mode(tmp_path / "planner" / "key.pem") == 0o600
    assert mode(tmp_path / "planner" / "cert.pem") & 0o044, "certificates are public"


def test_each_certificate_carries_its_name_as_common_name(tmp_path):
    make(tmp_path, ["planner", "mujoco-sim"], list(DEFAULT_HOSTS), report=quiet)
    for name in ("planner", "mujoco-sim"):
        subject = openssl("x509", "-in", str(tmp_path / name / "cert.pem"), "-noout",
                          "-subject", "-nameopt", "RFC2253")
        assert subject.strip() == f"subject=CN={name}"


def test_the_router_certificate_serves_tls_for_the_given_hosts(tmp_path):
    make(tmp_path, ["router"], ["router", "localhost", "10.0.0.5"], report=quiet)
    text = x509_text(tmp_path / "router" / "cert.pem")
    assert "DNS:router, DNS:localhost, IP Address:10.0.0.5" in text
    assert "TLS Web Server Authentication, TLS Web Client Authentication" in text
    assert "CA:FALSE" in text


def test_a_service_certificate_is_a_client_certificate_only(tmp_path):
    make(tmp_path, ["intent"], list(DEFAULT_HOSTS), report=quiet)
    text = x509_text(tmp_path / "intent" / "cert.pem")
    assert "TLS Web Client Authentication" in text
    assert "TLS Web Server Authentication" not in text
    assert "DNS:intent" in text


def test_the_authority_may_sign_but_not_create_sub_authorities(tmp_path):
    make(tmp_path, ["intent"], list(DEFAULT_HOSTS), report=quiet)
    text = x509_text(tmp_path / "ca" / "ca.pem")
    assert "CA:TRUE, pathlen:0" in text
    assert "Certificate Sign" in text


def test_making_again_keeps_what_exists_and_adds_new_names(tmp_path):
    make(tmp_path, ["planner"], list(DEFAULT_HOSTS), report=quiet)
    ca, planner = (tmp_path / "ca" / "ca.pem").read_bytes(), (
        tmp_path / "planner" / "cert.pem").read_bytes()
    lines = []
    issued = make(tmp_path, ["planner", "operator-anna"], list(DEFAULT_HOSTS),
                  report=lines.append)
    assert issued == ["operator-anna"]
    assert (tmp_path / "ca" / "ca.pem").read_bytes() == ca
    assert (tmp_path / "planner" / "cert.pem").read_bytes() == planner
    assert any(line.startswith("planner: kept") for line in lines)
    verified = openssl("verify", "-CAfile", str(tmp_path / "ca" / "ca.pem"),
                       str(tmp_path / "operator-anna" / "cert.pem"))
    assert verified.strip().endswith("OK"), "new names are signed by the same authority"


def test_force_reissues_the_named_certificates_with_the_same_authority(tmp_path):
    make(tmp_path, ["planner"], list(DEFAULT_HOSTS), report=quiet)
    ca, key = (tmp_path / "ca" / "ca.pem").read_bytes(), (
        tmp_path / "planner" / "key.pem").read_bytes()
    assert make(tmp_path, ["planner"], list(DEFAULT_HOSTS), force=True,
                report=quiet) == ["planner"]
    assert (tmp_path / "ca" / "ca.pem").read_bytes() == ca
    assert (tmp_path / "planner" / "key.pem").read_bytes() != key
    assert mode(tmp_path / "planner" / "key.pem") == 0o600


def test_an_authority_with_a_missing_half_is_refused(tmp_path):
    make(tmp_path, ["planner"], list(DEFAULT_HOSTS), report=quiet)
    (tmp_path / "ca" / "ca.key").unlink()
    with pytest.raises(CertError, match="only one of ca.pem and ca.key"):
        make(tmp_path, ["intent"], list(DEFAULT_HOSTS), report=quiet)


@pytest.mark.parametrize("name", ["Planner", "ca", "../etc", "a b", ""])
def test_bad_names_are_refused_before_anything_is_written(tmp_path, name):
    with pytest.raises(CertError):
        make(tmp_path / "out", ["planner", name], list(DEFAULT_HOSTS), report=quiet)
    assert not (tmp_path / "out").exists()


def test_check_name_accepts_kebab_case():
    assert check_name("operator-anna") == "operator-anna"


def test_a_missing_openssl_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    with pytest.raises(CertError, match="`openssl` was not found on the PATH; install it"):
        make(tmp_path / "out", ["planner"], list(DEFAULT_HOSTS), report=quiet)


# ------------------------------------------------------------------------------ the CLI


def cbgo(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "cbgo.cli.main", *args], capture_output=True,
                          text=True, timeout=60, env={**os.environ, **(env or {})})


def test_the_cli_makes_the_certificates_it_is_asked_for(tmp_path):
    result = cbgo("certs", "make", str(tmp_path), "--names", "router,planner",
                  "--host", "10.0.0.5", "--days", "30")
    assert result.returncode == 0, result.stderr
    assert "planner: issued" in result.stdout
    assert "for router, localhost, 127.0.0.1, 10.0.0.5" in result.stdout
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ca", "planner", "router"]
    assert "IP Address:10.0.0.5" in x509_text(tmp_path / "router" / "cert.pem")


def test_the_cli_says_why_it_failed(tmp_path):
    result = cbgo("certs", "make", str(tmp_path), "--names", "Planner")
    assert result.returncode == 2
    assert "bad certificate name 'Planner'" in result.stderr
    result = cbgo("certs", "make", str(tmp_path / "x"), env={"PATH": str(tmp_path / "none")})
    assert result.returncode == 2
    assert "`openssl` was not found" in result.stderr


def test_the_help_names_the_layout_and_the_options():
    result = cbgo("certs", "--help")
    assert result.returncode == 0
    assert "DIR/<name>/cert.pem" in result.stdout and "make" in result.stdout
    result = cbgo("certs", "make", "--help")
    assert result.returncode == 0
    for option in ("--names", "--host", "--days", "--force"):
        assert option in result.stdout
