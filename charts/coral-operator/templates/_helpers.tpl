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
- apiGroups: [""]
  resources: [configmaps]
  verbs: [get, list, watch, create, delete]
- apiGroups: [""]
  resources: [serviceaccounts]
  verbs: [create]
- apiGroups: [rbac.authorization.k8s.io]
  resources: [roles, rolebindings]
  verbs: [create]
- apiGroups: ["", events.k8s.io]
  resources: [events]
  verbs: [create, patch]
- apiGroups: [apps]
  resources: [controllerrevisions]
  verbs: [get, list, create, update, delete]
{{- end -}}
