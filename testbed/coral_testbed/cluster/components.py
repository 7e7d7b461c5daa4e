"""Command lines of the control-plane components, built from one `Layout` (pure functions).

`controlplane.start` runs them in this order: etcd, kube-apiserver, then kube-controller-manager,
kube-scheduler and kwok. Everything listens on 127.0.0.1 on ports chosen free at start, so several
control planes (a developer's and a test session's) can run side by side.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from coral_testbed.cluster import pki as pki_module
from coral_testbed.cluster.paths import Under

SERVICE_CIDR = "10.96.0.0/16"
# kwok hands out pod IPs from this CIDR starting at its address, so it starts at .1. It avoids
# kind's pod subnet (10.244.0.0/16), where kwok also runs against a kind cluster given by KUBECONFIG.
POD_CIDR = "10.250.0.1/16"
SERVICE_ACCOUNT_ISSUER = "https://kubernetes.default.svc.cluster.local"
# kwok manages Nodes carrying this label with the "online" value. A label rather than an annotation:
# kwok watches labels server-side, so changing the value (robot offline) makes it let go of the
# Node and stop renewing its lease; it filters annotations only as they arrive.
KWOK_LABEL = "coral.dev/simulation"
KWOK_ONLINE = "online"
KWOK_OFFLINE = "offline"


@dataclass(frozen=True)
class Heartbeats:
    """How robots heartbeat and how soon a silent one is declared unreachable (Ready=Unknown).

    kwok renews a robot's Lease every quarter of `lease_s`, as a kubelet does; the node-lifecycle
    controller checks every `monitor_period_s` for Leases unrenewed for `grace_s`. An offline robot
    so turns Unknown between `grace_s - lease_s / 4` and `grace_s + monitor_period_s` after it went.
    It is tainted unreachable (NoExecute) at once, unless another robot was tainted less than
    `1 / taints_per_s` seconds before: the controller's guard against evicting a whole fleet at once.
    """

    lease_s: int = 40
    grace_s: int = 30
    monitor_period_s: int = 5
    taints_per_s: float = 0.1

    def controller_manager_flags(self) -> list[str]:
        """The node-lifecycle controller's flags: a robot whose Lease went unrenewed for the grace
        period turns Ready=Unknown."""
        return [
            f"--node-monitor-grace-period={self.grace_s}s",
            f"--node-monitor-period={self.monitor_period_s}s",
            f"--node-eviction-rate={self.taints_per_s}",
        ]


DEV_HEARTBEATS = Heartbeats()
"""A developer's cluster: a kubelet's 40 s Lease (renewed every 10 s), offline robots noticed in
about 30 s."""

TEST_HEARTBEATS = Heartbeats(lease_s=12, grace_s=12, monitor_period_s=1, taints_per_s=1.0)
"""A test session's cluster: renewals every 3 s, four per grace period (one more than a developer's
cluster allows), so a robot is not lost to a busy moment, while tests that take one offline wait
about 12 s instead of 30, and up to 1 s more, not 10, when the robot of the test before was just
tainted. What the tests check does not depend on these lengths."""


@dataclass(frozen=True)
class Ports:
    etcd_client: int
    etcd_peer: int
    apiserver: int
    controller_manager: int
    scheduler: int
    kwok: int


@dataclass(frozen=True)
class Layout:
    """Everything a component's command line depends on."""

    state_dir: Path
    bin_dir: Path
    ports: Ports

    @property
    def pki(self) -> pki_module.Pki:
        return pki_module.Pki(self.state_dir / "pki")

    logs_dir = Under("state_dir", "logs")

    @property
    def server(self) -> str:
        return f"https://127.0.0.1:{self.ports.apiserver}"

    admin_kubeconfig = Under("state_dir", "kubeconfig")

    def kubeconfig_for(self, identity: str) -> Path:
        return self.admin_kubeconfig if identity == "admin" else self.state_dir / f"{identity}.kubeconfig"

    kwok_config = Under("state_dir", "kwok.yaml")
    audit_policy = Under("state_dir", "audit-policy.yaml")

    @property
    def audit_log(self) -> Path:
        """Every request a ServiceAccount made (`AUDIT_POLICY`), one JSON event per line."""
        return self.logs_dir / "audit.log"

    def to_json(self) -> dict[str, Any]:
        return {"state_dir": str(self.state_dir), "bin_dir": str(self.bin_dir), "ports": asdict(self.ports)}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Layout:
        return cls(Path(data["state_dir"]), Path(data["bin_dir"]), Ports(**data["ports"]))


def build_etcd(layout: Layout) -> list[str]:
    client = f"http://127.0.0.1:{layout.ports.etcd_client}"
    peer = f"http://127.0.0.1:{layout.ports.etcd_peer}"
    return [
        str(layout.bin_dir / "etcd"),
        "--name=coral-dev",
        f"--data-dir={layout.state_dir / 'etcd'}",
        f"--listen-client-urls={client}",
        f"--advertise-client-urls={client}",
        f"--listen-peer-urls={peer}",
        f"--initial-advertise-peer-urls={peer}",
        f"--initial-cluster=coral-dev={peer}",
        # A throwaway store: fsync-free writes keep start-up and tests fast on a shared disk.
        "--unsafe-no-fsync=true",
        "--quota-backend-bytes=2147483648",
        "--log-level=warn",
    ]


def build_apiserver(layout: Layout) -> list[str]:
    pki = layout.pki
    return [
        str(layout.bin_dir / "kube-apiserver"),
        f"--etcd-servers=http://127.0.0.1:{layout.ports.etcd_client}",
        "--bind-address=127.0.0.1",
        "--advertise-address=127.0.0.1",
        f"--secure-port={layout.ports.apiserver}",
        f"--tls-cert-file={pki.server_cert}",
        f"--tls-private-key-file={pki.server_key}",
        f"--client-ca-file={pki.ca_cert}",
        f"--service-account-key-file={pki.sa_pub}",
        f"--service-account-signing-key-file={pki.sa_key}",
        f"--service-account-issuer={SERVICE_ACCOUNT_ISSUER}",
        "--authorization-mode=Node,RBAC",
        f"--service-cluster-ip-range={SERVICE_CIDR}",
        "--allow-privileged=true",
        # As in a production cluster: the API server calls kubelets (logs, exec) at their InternalIP
        # with a client certificate, and a kubelet may touch only its own Node.
        f"--kubelet-client-certificate={pki.client_cert('kubelet-client')}",
        f"--kubelet-client-key={pki.client_key('kubelet-client')}",
        "--kubelet-preferred-address-types=InternalIP,Hostname",
        "--enable-admission-plugins=NodeRestriction",
        # Endpoints may not hold a loopback address, so the `kubernetes` Service gets none.
        "--endpoint-reconciler-type=none",
        "--profiling=false",
        f"--audit-policy-file={layout.audit_policy}",
        f"--audit-log-path={layout.audit_log}",
        "--audit-log-format=json",
        "--audit-log-maxsize=200",
        "--audit-log-maxbackup=1",
        "--v=1",
    ]


AUDIT_POLICY = """\
# Requests of ServiceAccounts only (an operator installed by its chart, executors, tenants' pods):
# what they asked and what they were answered, without bodies. The control plane's own components
# authenticate by certificate and are not recorded.
apiVersion: audit.k8s.io/v1
kind: Policy
omitStages: [RequestReceived, ResponseStarted]
rules:
  - level: Metadata
    userGroups: ["system:serviceaccounts"]
  - level: None
"""
"""Audit policy of the local kube-apiserver: tests read what an identity really did (and was refused)
from `Layout.audit_log` instead of inferring it from its logs."""


def build_controller_manager(layout: Layout, heartbeats: Heartbeats = DEV_HEARTBEATS) -> list[str]:
    pki = layout.pki
    return [
        str(layout.bin_dir / "kube-controller-manager"),
        f"--kubeconfig={layout.kubeconfig_for('controller-manager')}",
        "--bind-address=127.0.0.1",
        f"--secure-port={layout.ports.controller_manager}",
        f"--cert-dir={layout.state_dir / 'controller-manager-certs'}",
        "--controllers=*",
        "--leader-elect=false",
        *heartbeats.controller_manager_flags(),
        # Each controller acts as its own ServiceAccount, as in production clusters.
        "--use-service-account-credentials=true",
        f"--service-account-private-key-file={pki.sa_key}",
        f"--root-ca-file={pki.ca_cert}",
        f"--cluster-signing-cert-file={pki.ca_cert}",
        f"--cluster-signing-key-file={pki.ca_key}",
        f"--service-cluster-ip-range={SERVICE_CIDR}",
        "--profiling=false",
        "--v=1",
    ]


def build_scheduler(layout: Layout) -> list[str]:
    return [
        str(layout.bin_dir / "kube-scheduler"),
        f"--kubeconfig={layout.kubeconfig_for('scheduler')}",
        "--bind-address=127.0.0.1",
        f"--secure-port={layout.ports.scheduler}",
        f"--cert-dir={layout.state_dir / 'scheduler-certs'}",
        "--leader-elect=false",
        "--profiling=false",
        "--v=1",
    ]


def build_kwok(
    layout: Layout,
    kubeconfig: Path | None = None,
    extra: Sequence[str] = (),
    heartbeats: Heartbeats = DEV_HEARTBEATS,
) -> list[str]:
    """kwok as the controller of robot Nodes; `kubeconfig` points it at another cluster if given,
    `extra` flags follow (a benchmark's `--config` of more workers, say)."""
    return [
        str(layout.bin_dir / "kwok"),
        f"--config={layout.kwok_config}",
        f"--kubeconfig={kubeconfig or layout.admin_kubeconfig}",
        "--manage-all-nodes=false",
        f"--manage-nodes-with-label-selector={KWOK_LABEL}={KWOK_ONLINE}",
        f"--node-lease-duration-seconds={heartbeats.lease_s}",
        f"--server-address=127.0.0.1:{layout.ports.kwok}",
        "--node-ip=127.0.0.1",
        f"--node-port={layout.ports.kwok}",
        f"--cidr={POD_CIDR}",
        *extra,
    ]
