"""coral-kind-net: a node's pod network for a kind cluster, kept in step with the cluster's Nodes.

Runs on every node (hostNetwork, privileged, the node's root at /host). Every few seconds it reads
the Nodes from the API server with its ServiceAccount and
- writes /etc/cni/net.d/10-coral-kind.conflist for its own node's podCIDR: the ptp plugin (a veth
  per pod with host routes, as kindnetd does, so replies to Service traffic pass the node's
  conntrack) with host-local addresses, plus portmap;
- routes each other node's podCIDR via that node's InternalIP (the nodes share one Docker network),
  with the node's own `ip` (`chroot /host`), since the image carries none.
Writes are atomic and only made when something changed.
"""

import ipaddress
import json
import os
import ssl
import subprocess
import sys
import time
import urllib.request

SERVICE_ACCOUNT = "/var/run/secrets/kubernetes.io/serviceaccount"
CNI_CONFIG = "/etc/cni/net.d/10-coral-kind.conflist"
PERIOD_SECONDS = 5


def api_server() -> str:
    # kind patches CONTROL_PLANE_ENDPOINT in, so the network comes up before kube-proxy's Service rules.
    endpoint = os.environ.get("CONTROL_PLANE_ENDPOINT")
    if endpoint:
        return f"https://{endpoint}"
    return f"https://{os.environ['KUBERNETES_SERVICE_HOST']}:{os.environ['KUBERNETES_SERVICE_PORT']}"


def read_nodes() -> list[dict]:
    with open(f"{SERVICE_ACCOUNT}/token") as token_file:
        token = token_file.read().strip()
    context = ssl.create_default_context(cafile=f"{SERVICE_ACCOUNT}/ca.crt")
    # The API server's certificate names the control plane's container, not always this address.
    context.check_hostname = False
    request = urllib.request.Request(
        f"{api_server()}/api/v1/nodes", headers={"Authorization": f"Bearer {token}"}
    )
    with urllib.request.urlopen(request, context=context, timeout=10) as response:
        return json.loads(response.read())["items"]


def internal_ip(node: dict) -> str | None:
    """The node's IPv4 InternalIP; None for a loopback one (a kwok Node's: no machine to route to)."""
    for address in node.get("status", {}).get("addresses", []):
        if address.get("type") != "InternalIP":
            continue
        try:
            parsed = ipaddress.ip_address(address.get("address", ""))
        except ValueError:
            continue
        if parsed.version == 4 and not parsed.is_loopback:
            return str(parsed)
    return None


def conflist(pod_cidr: str) -> str:
    return json.dumps(
        {
            "cniVersion": "0.4.0",
            "name": "coral-kind",
            "plugins": [
                {
                    "type": "ptp",
                    "ipMasq": True,
                    "mtu": 1500,
                    "ipam": {
                        "type": "host-local",
                        "dataDir": "/run/cni-ipam-state",
                        "ranges": [[{"subnet": pod_cidr}]],
                        "routes": [{"dst": "0.0.0.0/0"}],
                    },
                },
                {"type": "portmap", "capabilities": {"portMappings": True}},
            ],
        },
        indent=2,
    )


def write_if_changed(path: str, text: str) -> bool:
    try:
        with open(path) as current:
            if current.read() == text:
                return False
    except OSError:
        pass
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path + ".tmp", "w") as sink:
        sink.write(text)
    os.replace(path + ".tmp", path)
    return True


def route(cidr: str, via: str) -> None:
    subprocess.run(["chroot", "/host", "ip", "route", "replace", cidr, "via", via], check=True)


def sync(own_name: str, routed: dict[str, str]) -> None:
    for node in read_nodes():
        name = node["metadata"]["name"]
        cidr = node.get("spec", {}).get("podCIDR")
        address = internal_ip(node)
        if not cidr:
            continue
        if name == own_name:
            if write_if_changed(CNI_CONFIG, conflist(cidr)):
                print(f"Wrote {CNI_CONFIG} for podCIDR {cidr}", flush=True)
        elif address and routed.get(cidr) != address:
            route(cidr, address)
            routed[cidr] = address
            print(f"Routed {cidr} via {address} ({name})", flush=True)


def main() -> None:
    own_name = os.environ["NODE_NAME"]
    routed: dict[str, str] = {}
    while True:
        try:
            sync(own_name, routed)
        except Exception as error:  # The API server restarting must not end the node's network.
            print(f"Sync failed, retrying: {error}", file=sys.stderr, flush=True)
        time.sleep(PERIOD_SECONDS)


if __name__ == "__main__":
    main()
