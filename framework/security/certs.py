"""A small certificate authority for multi-host graphs (docs/security.md).

``handflow certs init DIR`` writes ``ca.pem``/``ca.key``; ``handflow certs add-host DIR NAME`` writes
``NAME.pem``/``NAME.key`` signed by that CA, with ``NAME`` as common name (the name Zenoh's access
control matches) and as DNS name, plus ``localhost``/``127.0.0.1`` so one machine can run both
sides.  :func:`check_host_files` turns a missing, expired or foreign certificate into one clear
sentence before Zenoh sees it.  Needs the ``secure`` extra (the ``cryptography`` library).
"""

from __future__ import annotations

import datetime as dt
import ipaddress
from pathlib import Path

CA_CERT = "ca.pem"
CA_KEY = "ca.key"
EXTRA_HINT = "install it with: pip install 'handflow[secure]'"


class CertError(ValueError):
    """A certificate file that is missing, expired, unreadable or not signed by the graph's CA."""


def _crypto():
    try:
        from cryptography import x509
        from cryptography.hazmat.primitives import hashes, serialization
        from cryptography.hazmat.primitives.asymmetric import ec
        from cryptography.x509.oid import NameOID
    except ImportError:  # pragma: no cover - depends on the environment
        raise CertError(f"certificates need the 'cryptography' library; {EXTRA_HINT}") from None
    return x509, hashes, serialization, ec, NameOID


def host_files(directory: Path, host: str) -> tuple[Path, Path]:
    return directory / f"{host}.pem", directory / f"{host}.key"


def _write_key_and_cert(key, cert, key_path: Path, cert_path: Path) -> None:
    _, _, serialization, _, _ = _crypto()
    key_path.write_bytes(
        key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption())
    )
    key_path.chmod(0o600)
    cert_path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))


def _name(common_name: str):
    x509, _, _, _, NameOID = _crypto()
    return x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, common_name)])


def init_ca(directory: Path, days: int = 3650, name: str = "handflow CA") -> Path:
    """Create ``ca.pem``/``ca.key`` in ``directory``; refuses to overwrite an existing CA."""
    x509, hashes, _, ec, _ = _crypto()
    directory.mkdir(parents=True, exist_ok=True)
    if (directory / CA_KEY).exists():
        raise CertError(f"{directory / CA_KEY} already exists; use another directory or delete it to start over")
    key = ec.generate_private_key(ec.SECP256R1())
    now = dt.datetime.now(dt.timezone.utc)
    cert = (
        x509.CertificateBuilder()
        .subject_name(_name(name))
        .issuer_name(_name(name))
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - dt.timedelta(minutes=5))
        .not_valid_after(now + dt.timedelta(days=days))
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(x509.KeyUsage(False, False, False, False, False, True, True, False, False), critical=True)
        .sign(key, hashes.SHA256())
    )
    _write_key_and_cert(key, cert, directory / CA_KEY, directory / CA_CERT)
    return directory / CA_CERT


def add_host(directory: Path, host: str, days: int = 825, not_before: dt.datetime | None = None) -> Path:
    """Create ``HOST.pem``/``HOST.key`` signed by the CA in ``directory``."""
    x509, hashes, serialization, ec, _ = _crypto()
    ca_cert_path, ca_key_path = directory / CA_CERT, directory / CA_KEY
    if not ca_key_path.exists():
        raise CertError(f"no CA in {directory}: run `handflow certs init {directory}` first")
    ca_cert = x509.load_pem_x509_certificate(ca_cert_path.read_bytes())
    ca_key = serialization.load_pem_private_key(ca_key_path.read_bytes(), password=None)
    key = ec.generate_private_key(ec.SECP256R1())
    start = not_before or dt.datetime.now(dt.timezone.utc) - dt.timedelta(minutes=5)
    alt = [x509.DNSName(host), x509.DNSName("localhost"), x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]
    try:
        alt.append(x509.IPAddress(ipaddress.ip_address(host)))
    except ValueError:
        pass
    cert = (
        x509.CertificateBuilder()
        .subject_name(_name(host))
        .issuer_name(ca_cert.subject)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(start)
        .not_valid_after(start + dt.timedelta(days=days))
        .add_extension(x509.SubjectAlternativeName(alt), critical=False)
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .sign(ca_key, hashes.SHA256())
    )
    cert_path, key_path = host_files(directory, host)
    _write_key_and_cert(key, cert, key_path, cert_path)
    return cert_path


def _load_cert(path: Path, what: str):
    x509 = _crypto()[0]
    if not path.exists():
        raise CertError(f"{what} {path} is missing")
    try:
        return x509.load_pem_x509_certificate(path.read_bytes())
    except ValueError as exc:
        raise CertError(f"{what} {path} is not a PEM certificate ({exc})") from None


def check_host_files(directory: Path, host: str) -> tuple[Path, Path, Path]:
    """(CA, certificate, key) of ``host`` after checking presence, validity dates and the CA signature."""
    ca = _load_cert(directory / CA_CERT, "CA certificate")
    cert_path, key_path = host_files(directory, host)
    hint = f"create it with `handflow certs add-host {directory} {host}`"
    if not cert_path.exists() or not key_path.exists():
        raise CertError(f"no certificate for host '{host}' in {directory} ({cert_path.name}, {key_path.name}); {hint}")
    cert = _load_cert(cert_path, "certificate")
    now = dt.datetime.now(dt.timezone.utc)
    if cert.not_valid_after_utc < now:
        raise CertError(f"certificate {cert_path} expired on {cert.not_valid_after_utc:%Y-%m-%d}; renew it: {hint}")
    if cert.not_valid_before_utc > now:
        raise CertError(f"certificate {cert_path} is not valid before {cert.not_valid_before_utc:%Y-%m-%d %H:%M} UTC")
    try:
        cert.verify_directly_issued_by(ca)
    except (ValueError, TypeError, Exception) as exc:  # InvalidSignature has no common base but Exception
        raise CertError(
            f"certificate {cert_path} was not signed by the CA in {directory / CA_CERT} ({type(exc).__name__}); "
            f"every host of a graph needs a certificate from the same CA: {hint}"
        ) from None
    return directory / CA_CERT, cert_path, key_path
