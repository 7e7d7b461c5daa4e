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

{{/* What the operator does in each namespace it serves. */}}
{{- define "coral-operator.namespacedRules" -}}
- apiGroups: [coral.dev]
  resources: [coralsystems]
  verbs: [get, list, watch, patch]
- apiGroups: [coral.dev]
  resources: [coralinstances]
  verbs: [get, list, watch, create, patch, delete]
- apiGroups: [coral.dev]
  resources: [coralsystems/status, coralinstances/status]
  verbs: [get, patch]
- apiGroups: [""]
  resources: [pods]
  verbs: [get, list, watch, create, patch, delete, deletecollection]
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
- apiGroups: ["", events.k8s.io]
  resources: [events]
  verbs: [create, patch]
- apiGroups: [apps]
  resources: [controllerrevisions]
  verbs: [get, list, create, update, delete]
{{- end -}}
