"""Certificates and keys for the local control plane, made with the openssl command line tool.

Called once per `up` by `controlplane.start`. One throwaway CA signs the API server's serving
certificate and one client certificate per identity (admin in system:masters, the controller
manager and the scheduler under their bootstrap RBAC names), so RBAC behaves as in a real
cluster. A separate key signs ServiceAccount tokens. EC P-256 keys keep generation fast on busy
machines.
"""

from __future__ import annotations

import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

from coral_testbed.cluster.paths import Under

# The in-cluster names and the first service IP, so in-cluster clients could verify the server too.
SERVER_SANS = (
    "IP:127.0.0.1",
    "DNS:localhost",
    "DNS:kubernetes",
    "DNS:kubernetes.default",
    "DNS:kubernetes.default.svc",
    "DNS:kubernetes.default.svc.cluster.local",
    "IP:10.96.0.1",
)

# name -> (common name, organization) of each client identity.
CLIENTS: dict[str, tuple[str, str | None]] = {
    "admin": ("coral-admin", "system:masters"),
    "controller-manager": ("system:kube-controller-manager", None),
    "scheduler": ("system:kube-scheduler", None),
}

# The API server's identity towards kubelets (logs, exec, port-forward); kubelets authorize it by
# asking the API server, and system:masters may do everything there.
KUBELET_CLIENT = ("kube-apiserver-kubelet-client", "system:masters")

_REQ_CONFIG = "[req]\ndistinguished_name = dn\nprompt = no\n[dn]\nCN = placeholder\n"


class PkiError(RuntimeError):
    """openssl failed; the message carries its command and output."""


@dataclass(frozen=True)
class Pki:
    """Paths of every file the components read."""

    dir: Path

    ca_cert = Under("dir", "ca.crt")
    ca_key = Under("dir", "ca.key")
    server_cert = Under("dir", "apiserver.crt")
    server_key = Under("dir", "apiserver.key")
    sa_key = Under("dir", "service-account.key")
    sa_pub = Under("dir", "service-account.pub")

    def client_cert(self, name: str) -> Path:
        return self.dir / f"{name}.crt"

    def client_key(self, name: str) -> Path:
        return self.dir / f"{name}.key"


def _openssl(*args: str, cwd: Path) -> None:
    openssl = shutil.which("openssl")
    if openssl is None:
        raise PkiError("the openssl command is needed to create the local control plane's certificates")
    result = subprocess.run([openssl, *args], cwd=cwd, capture_output=True, text=True, check=False)
    if result.returncode != 0:
        raise PkiError(f"openssl {' '.join(args)} failed: {result.stderr.strip()}")


def _new_key(path: Path) -> None:
    _openssl(
        "genpkey",
        "-algorithm",
        "EC",
        "-pkeyopt",
        "ec_paramgen_curve:P-256",
        "-out",
        str(path),
        cwd=path.parent,
    )
    path.chmod(0o600)


def build_subject(common_name: str, organization: str | None) -> str:
    return (f"/O={organization}" if organization else "") + f"/CN={common_name}"


def build_extensions(server: bool, sans: tuple[str, ...] = ()) -> str:
    lines = [
        "[v3]",
        "basicConstraints = critical,CA:FALSE",
        "keyUsage = critical,digitalSignature,keyEncipherment",
        f"extendedKeyUsage = {'serverAuth' if server else 'clientAuth'}",
    ]
    if sans:
        lines.append(f"subjectAltName = {','.join(sans)}")
    return "\n".join(lines) + "\n"


def _sign(pki: Pki, name: str, subject: str, extensions: str, serial: int) -> None:
    """Writes `name`.key and `name`.crt, signed by the CA (serials must differ per certificate)."""
    key, cert = pki.dir / f"{name}.key", pki.dir / f"{name}.crt"
    csr, ext, cfg = pki.dir / f"{name}.csr", pki.dir / f"{name}.ext", pki.dir / "req.cnf"
    _new_key(key)
    _openssl(
        "req", "-new", "-config", str(cfg), "-key", str(key), "-subj", subject, "-out", str(csr), cwd=pki.dir
    )
    ext.write_text(extensions)
    _openssl(
        "x509",
        "-req",
        "-in",
        str(csr),
        "-CA",
        str(pki.ca_cert),
        "-CAkey",
        str(pki.ca_key),
        "-set_serial",
        str(serial),
        "-days",
        "3650",
        "-sha256",
        "-extfile",
        str(ext),
        "-extensions",
        "v3",
        "-out",
        str(cert),
        cwd=pki.dir,
    )
    csr.unlink()
    ext.unlink()


def create_pki(directory: Path) -> Pki:
    """Writes a fresh CA, server and client certificates and the ServiceAccount key pair."""
    directory.mkdir(parents=True, exist_ok=True)
    pki = Pki(directory)
    (directory / "req.cnf").write_text(_REQ_CONFIG)
    _new_key(pki.ca_key)
    _openssl(
        "req",
        "-x509",
        "-new",
        "-config",
        str(directory / "req.cnf"),
        "-key",
        str(pki.ca_key),
        "-subj",
        "/CN=coral-dev-cluster-ca",
        "-days",
        "3650",
        "-sha256",
        "-addext",
        "basicConstraints=critical,CA:TRUE",
        "-addext",
        "keyUsage=critical,keyCertSign,cRLSign,digitalSignature",
        "-out",
        str(pki.ca_cert),
        cwd=directory,
    )
    _sign(pki, "apiserver", "/CN=kube-apiserver", build_extensions(server=True, sans=SERVER_SANS), serial=2)
    for serial, (name, (common_name, organization)) in enumerate(CLIENTS.items(), start=3):
        _sign(pki, name, build_subject(common_name, organization), build_extensions(server=False), serial)
    common_name, organization = KUBELET_CLIENT
    _sign(pki, "kubelet-client", build_subject(common_name, organization), build_extensions(server=False), 99)
    _new_key(pki.sa_key)
    _openssl("pkey", "-in", str(pki.sa_key), "-pubout", "-out", str(pki.sa_pub), cwd=directory)
    return pki

