{{- define "coral-operator.name" -}}
{{- .Release.Name | trunc 63 | trimSuffix "-" -}}
{{- end -}}

{{- define "coral-operator.serviceAccountName" -}}
{{- default (include "coral-operator.name" .) .Values.serviceAccount.name -}}
{{- end -}}

{{- define "coral-operator.labels" -}}
app.kubernetes.io/name: coral-operator
app.kubernetes.io/instance: {{ .Release.Name }}
app.kubernetes.io/version: {{ .Chart.AppVersion | quote }}
app.kubernetes.io/managed-by: {{ .Release.Service }}
helm.sh/chart: {{ printf "%s-%s" .Chart.Name .Chart.Version }}
{{- end -}}

{{- define "coral-operator.selectorLabels" -}}
app.kubernetes.io/name: coral-operator
app.kubernetes.io/instance: {{ .Release.Name }}
{{- end -}}

{{/* What the operator does in each namespace it serves: no more than it asks for as a system is
     created, grows, changes, rolls back and goes (tests/integration/operator/test_helm_chart.py
     compares the two both ways). */}}
{{- define "coral-operator.namespacedRules" -}}
{{- /* get: a system whose files are too large to keep in memory is read again by each pass. */}}
- apiGroups: [coral.dev]
  resources: [coralsystems]
  verbs: [get, list, watch]
{{- /* get: an instance name that answers 409 is read to tell whose it is. */}}
- apiGroups: [coral.dev]
  resources: [coralinstances]
  verbs: [get, list, watch, create, patch, delete]
- apiGroups: [coral.dev]
  resources: [coralsystems/status, coralinstances/status]
  verbs: [patch]
- apiGroups: [""]
  resources: [pods]
  verbs: [list, watch, create, patch, delete, deletecollection]
{{- /* ConfigMaps, the executors' ServiceAccount, Role and RoleBinding: created once, read back when
     a create answers 409 (a second robot joining, a restart), and patched only to hand a recreated
     system the objects its predecessor left (kube.applying.create_owned). */}}
- apiGroups: [""]
  resources: [configmaps]
  verbs: [get, list, watch, create, patch, delete]
- apiGroups: [""]
  resources: [serviceaccounts]
  verbs: [get, create, patch]
- apiGroups: [rbac.authorization.k8s.io]
  resources: [roles, rolebindings]
  verbs: [get, create, patch]
- apiGroups: [""]
  resources: [events]
  verbs: [create]
- apiGroups: [apps]
  resources: [controllerrevisions]
  verbs: [get, list, create, update, delete]
{{- end -}}
