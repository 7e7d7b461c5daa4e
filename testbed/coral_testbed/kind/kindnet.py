"""The pod network the node image ships as /kind/manifests/default-cni.yaml (kind applies it).

kind's own CNI, kindnetd, cannot be built here (its Go module is not served), so the node image
carries the project's: `coral-kind-net` (testbed/images/kind-net), a hostNetwork DaemonSet that
writes each node's CNI config and routes the other nodes' podCIDRs. Pure; called by `nodeimage`.
"""

from __future__ import annotations

IMAGE = "docker.io/coral/kind-net:preloaded"
"""The name the node image preloads the agent under (never pulled: `imagePullPolicy: Never`)."""

# kind adds CONTROL_PLANE_ENDPOINT to the first container's env of a manifest that says
# "would you kindly patch this file", so the network comes up before kube-proxy serves Services.
_MANIFEST = """\
# coral-kind-net, the pod network of Coral's kind node image; would you kindly patch this file
apiVersion: v1
kind: ServiceAccount
metadata:
  name: coral-kind-net
  namespace: kube-system
---
apiVersion: rbac.authorization.k8s.io/v1
kind: ClusterRole
metadata:
  name: coral-kind-net
rules:
- apiGroups: [""]
  resources: [nodes]
  verbs: [get, list, watch]
---
apiVersion: rbac.authorization.k8s.io/v1
kind: ClusterRoleBinding
metadata:
  name: coral-kind-net
roleRef:
  apiGroup: rbac.authorization.k8s.io
  kind: ClusterRole
  name: coral-kind-net
subjects:
- kind: ServiceAccount
  name: coral-kind-net
  namespace: kube-system
---
apiVersion: apps/v1
kind: DaemonSet
metadata:
  name: coral-kind-net
  namespace: kube-system
  labels: {app: coral-kind-net}
spec:
  selector:
    matchLabels: {app: coral-kind-net}
  template:
    metadata:
      labels: {app: coral-kind-net}
    spec:
      hostNetwork: true
      dnsPolicy: Default
      # Not on kwok's simulated robots: no machine behind them to give a network.
      affinity:
        nodeAffinity:
          requiredDuringSchedulingIgnoredDuringExecution:
            nodeSelectorTerms:
            - matchExpressions:
              - {key: type, operator: NotIn, values: [kwok]}
      priorityClassName: system-node-critical
      serviceAccountName: coral-kind-net
      tolerations:
      - operator: Exists
      containers:
      - name: coral-kind-net
        image: %(image)s
        imagePullPolicy: Never
        env:
        - name: NODE_NAME
          valueFrom:
            fieldRef: {fieldPath: spec.nodeName}
        securityContext:
          privileged: true
        resources:
          requests: {cpu: 10m, memory: 20Mi}
        volumeMounts:
        - {name: cni-config, mountPath: /etc/cni/net.d}
        - {name: host, mountPath: /host, readOnly: true}
      volumes:
      - name: cni-config
        hostPath: {path: /etc/cni/net.d, type: DirectoryOrCreate}
      - name: host
        hostPath: {path: /}
"""


def build_manifest(image: str = IMAGE) -> str:
    """The ServiceAccount, RBAC and DaemonSet of coral-kind-net, running `image`."""
    return _MANIFEST % {"image": image}
