"""Make the certificates of a cbgo network secured by Zenoh mutual TLS (with `openssl`).

`cbgo certs make DIR` creates a private certificate authority and, signed by it, one
certificate per process whose common name (CN) is the process's name. The router's access
control list (deploy/tls/router.json5) grants rights by that CN: only `planner` (and routers)
may query `<prefix>/robot/act`. Layout::

    DIR/ca/ca.pem, ca.key         the authority; ca.key signs, keep it off the service hosts
    DIR/<name>/ca.pem             a copy of the authority's certificate (to verify the peer)
    DIR/<name>/cert.pem, key.pem  the process's certificate (CN=<name>) and private key

Copy `DIR/<name>/` to the machine that runs <name>, and only that directory. Private keys are
written with mode 0600. Running `make` again keeps what exists, reuses the authority and adds
missing names; `--force` re-issues the named certificates.

The router's certificate is also a server certificate: its names (`--host`) must include
every host name or IP address clients connect to (`tls/<host>:7447`), since clients check it.

Examples::

    cbgo certs make ~/cbgo-certs          # authority, router, every service, operator
    cbgo certs make ~/cbgo-certs --host robot-pc --host 10.0.0.5 --names router --force
                                          # re-issue the router's for the names clients use
    cbgo certs make ~/cbgo-certs --names operator-anna      # one more client certificate;
                                          # it may do nothing until router.json5 lists it
"""

from __future__ import annotations

import argparse
import os
import secrets
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from ipaddress import ip_address
from pathlib import Path

from cbgo.keys import check_service_name
from cbgo.registry import ROUTER, SERVICES

# Besides the registry's services (dry-robot among them): the operator's CLI tools.
EXTRA_NAMES = ("operator",)
DEFAULT_HOSTS = ("router", "localhost", "127.0.0.1")
DEFAULT_DAYS = 825
CA_NAME = "cbgo network CA"

# A configuration of our own, so that the system's openssl.cnf changes nothing.
OPENSSL_CONFIG = """\
[req]
distinguished_name = dn
prompt = no
[dn]
CN = unused
[authority]
basicConstraints = critical, CA:TRUE, pathlen:0
keyUsage = critical, keyCertSign, cRLSign
subjectKeyIdentifier = hash
[client]
basicConstraints = critical, CA:FALSE
keyUsage = critical, digitalSignature
extendedKeyUsage = clientAuth
subjectKeyIdentifier = hash
authorityKeyIdentifier = keyid
subjectAltName = {client_names}
[router]
basicConstraints = critical, CA:FALSE
keyUsage = critical, digitalSignature
extendedKeyUsage = serverAuth, clientAuth
subjectKeyIdentifier = hash
authorityKeyIdentifier = keyid
subjectAltName = {router_names}
"""


class CertError(Exception):
    """A certificate could not be made; the message says why and what to do."""


def default_names() -> list[str]:
    """Returns the router, every registered service, the dry-run robot and `operator`."""
    names = [ROUTER, *(s.name for s in SERVICES), *EXTRA_NAMES]
    return list(dict.fromkeys(names))


def subject_alt_names(names: list[str]) -> str:
    """Returns an openssl subjectAltName value: ``DNS:router, IP:127.0.0.1``."""
    parts = []
    for name in names:
        try:
            parts.append(f"IP:{ip_address(name)}")
        except ValueError:
            parts.append(f"DNS:{name}")
    return ", ".join(parts)


def write_private(path: Path, data: bytes) -> None:
    """Writes a private key readable by its owner only (0600 from the start, never wider)."""
    path.unlink(missing_ok=True)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "wb") as f:
        f.write(data)
    os.chmod(path, 0o600)  # the umask may have narrowed it further; make it exactly 0600


@dataclass
class Openssl:
    """Runs `openssl` with a configuration file of our own in a scratch directory."""

    binary: str
    scratch: Path

    @classmethod
    def find(cls, scratch: Path) -> Openssl:
        """Returns a runner, or raises CertError if no `openssl` is on the PATH."""
        binary = shutil.which("openssl")
        if binary is None:
            raise CertError("`openssl` was not found on the PATH; install it (Debian/Ubuntu: "
                            "apt-get install openssl, macOS: brew install openssl) and retry")
        return cls(binary, scratch)

    def __call__(self, *args: str, stdin: bytes | None = None) -> bytes:
        """Runs ``openssl ARGS``; returns its stdout or raises CertError with its stderr."""
        result = subprocess.run([self.binary, *args], input=stdin, capture_output=True,
                                check=False)
        if result.returncode != 0:
            raise CertError(f"openssl {args[0]} failed: "
                            f"{result.stderr.decode(errors='replace').strip()}")
        return result.stdout

    def write_config(self, hosts: list[str], client_name: str) -> Path:
        """Writes the openssl configuration for one certificate; returns its path."""
        path = self.scratch / "openssl.cnf"
        path.write_text(OPENSSL_CONFIG.format(client_names=subject_alt_names([client_name]),
                                              router_names=subject_alt_names(hosts)))
        return path

    def new_key(self) -> bytes:
        """Returns a new EC P-256 private key (PKCS#8 PEM), which rustls reads."""
        return self("genpkey", "-algorithm", "EC", "-pkeyopt", "ec_paramgen_curve:P-256")


def make_authority(ssl: Openssl, ca_dir: Path, days: int) -> None:
    """Creates the self-signed authority in ca_dir (ca.pem, ca.key)."""
    ca_dir.mkdir(parents=True, exist_ok=True)
    os.chmod(ca_dir, 0o700)
    key_path = ca_dir / "ca.key"
    write_private(key_path, ssl.new_key())
    config = ssl.write_config([], CA_NAME)
    cert = ssl("req", "-x509", "-new", "-key", str(key_path), "-subj", f"/CN={CA_NAME}",
               "-days", str(days), "-sha256", "-config", str(config),
               "-extensions", "authority")
    (ca_dir / "ca.pem").write_bytes(cert)


def issue(ssl: Openssl, ca_dir: Path, out: Path, name: str, hosts: list[str],
          days: int) -> None:
    """Issues out/{cert.pem,key.pem} for CN=name, signed by the authority, and copies ca.pem.

    The router's certificate serves TLS for `hosts` and is also a client certificate (routers
    connect to each other); the others are client certificates only.
    """
    out.mkdir(parents=True, exist_ok=True)
    key_path = out / "key.pem"
    write_private(key_path, ssl.new_key())
    config = ssl.write_config(hosts, name)
    request = ssl("req", "-new", "-key", str(key_path), "-subj", f"/CN={name}",
                  "-config", str(config))
    cert = ssl("x509", "-req", "-CA", str(ca_dir / "ca.pem"), "-CAkey", str(ca_dir / "ca.key"),
               "-set_serial", f"0x{secrets.token_hex(16)}", "-days", str(days), "-sha256",
               "-extfile", str(config), "-extensions", ROUTER if name == ROUTER else "client",
               stdin=request)
    (out / "cert.pem").write_bytes(cert)
    shutil.copyfile(ca_dir / "ca.pem", out / "ca.pem")


def make(directory: Path, names: list[str], hosts: list[str], days: int = DEFAULT_DAYS,
         force: bool = False, report=print) -> list[str]:
    """Creates the authority (if missing) and a certificate per name; returns the names issued.

    Args:
        directory: where to write (created if missing).
        names: common names, one certificate each (`router` gets the server certificate).
        hosts: the router's DNS names and IP addresses.
        days: validity of new certificates.
        force: re-issue certificates that exist already (the authority is always kept).
        report: called with one line per thing done.

    Raises:
        CertError: openssl missing or failing, a bad name, or a half-present authority.
    """
    for name in names:
        check_name(name)
    directory.mkdir(parents=True, exist_ok=True)
    ca_dir = directory / "ca"
    with tempfile.TemporaryDirectory(prefix="cbgo-certs-") as scratch:
        ssl = Openssl.find(Path(scratch))
        if ensure_authority(ssl, ca_dir, days):
            report(f"authority: created {ca_dir / 'ca.pem'} (its key ca.key stays here)")
        else:
            report(f"authority: kept {ca_dir / 'ca.pem'}")
        issued = []
        for name in names:
            out = directory / name
            if (out / "cert.pem").exists() and not force:
                report(f"{name}: kept {out} (--force re-issues it)")
                continue
            issue(ssl, ca_dir, out, name, hosts, days)
            issued.append(name)
            extra = f" for {', '.join(hosts)}" if name == ROUTER else ""
            report(f"{name}: issued {out / 'cert.pem'} (CN={name}){extra}")
    return issued


def ensure_authority(ssl: Openssl, ca_dir: Path, days: int) -> bool:
    """Creates the authority unless both of its files exist; returns whether it created it."""
    present = [(ca_dir / f).exists() for f in ("ca.pem", "ca.key")]
    if all(present):
        return False
    if any(present):
        raise CertError(f"{ca_dir} holds only one of ca.pem and ca.key; restore the other, or "
                        "remove the directory to start a new authority (every certificate must "
                        "then be made again)")
    make_authority(ssl, ca_dir, days)
    return True


def check_name(name: str) -> str:
    """Returns a usable common name, or raises CertError (names are also directory names)."""
    if name == "ca":
        raise CertError("'ca' is the authority's directory; choose another name")
    try:
        return check_service_name(name)
    except Exception as e:  # ConfigError: reworded for this tool
        raise CertError(f"bad certificate name {name!r}: use lower-case kebab-case, e.g. "
                        "'planner' or 'operator-anna'") from e


def split_list(values: list[str] | None) -> list[str]:
    """Returns repeated and comma-separated flag values as one list."""
    return [v.strip() for value in values or [] for v in value.split(",") if v.strip()]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Adds the `make` sub-verb and its flags."""
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    make_parser = actions.add_parser(
        "make", help="create the authority and the certificates in DIR",
        description="Create (or complete) DIR: the authority in DIR/ca, and DIR/<name>/ with "
                    "ca.pem, cert.pem and key.pem (mode 0600) for each name.")
    make_parser.add_argument("directory", metavar="DIR", type=Path,
                             help="where to write the certificates (created if missing)")
    make_parser.add_argument(
        "--names", action="append", metavar="NAME",
        help="common names to issue, repeatable or comma-separated; a name the router's ACL "
             "(deploy/tls/router.json5) does not list may do nothing [default: "
             f"{', '.join(default_names())}]")
    make_parser.add_argument(
        "--host", action="append", metavar="NAME_OR_IP",
        help="a DNS name or IP address clients use to reach the router; repeatable, added to "
             f"{', '.join(DEFAULT_HOSTS)}")
    make_parser.add_argument("--days", type=int, default=DEFAULT_DAYS,
                             help=f"validity of new certificates in days [{DEFAULT_DAYS}]")
    make_parser.add_argument("--force", action="store_true",
                             help="re-issue the named certificates that exist already")


def run(args: argparse.Namespace) -> int:
    """Makes the certificates; returns 0, or 2 with the reason on stderr."""
    from cbgo.cli.common import fail

    names = split_list(args.names) or default_names()
    hosts = list(dict.fromkeys([*DEFAULT_HOSTS, *split_list(args.host)]))
    if args.days < 1:
        fail(f"--days {args.days}: a certificate must be valid for at least 1 day", 2)
    try:
        make(args.directory, names, hosts, args.days, args.force)
    except CertError as e:
        fail(str(e), 2)
    except OSError as e:
        where = f" ({e.filename})" if e.filename and str(e.filename) != str(args.directory) else ""
        fail(f"cannot write to {args.directory}{where}: {e.strerror or e}; choose a directory "
             "you can write to", 2)
    print(f"copy {args.directory}/<name>/ to the machine that runs <name>; keep "
          f"{args.directory}/ca/ca.key off the service hosts")
    return 0
