-- Argo CD health check for coral.dev CoralSystem and CoralInstance (docs/verdicts.md).
-- Uses only what Argo CD's Lua sandbox opens (base, table): no string library.
-- Degraded: Stalled=True (a refused spec, a failed health gate, a rollback, a failed robot), a
-- rolled-back system (it does not run its spec's revision), or an instance whose tree FAILED.
-- Suspended: a rollout paused by spec.rollout.paused. Healthy: Ready=True for the current
-- generation. Progressing: anything else, including a status not yet written for this generation.
local hs = { status = "Progressing", message = "Waiting for the Coral operator to report status" }
if obj.status == nil or obj.status.conditions == nil then
  return hs
end
local generation = obj.metadata and obj.metadata.generation
if generation ~= nil and (obj.status.observedGeneration == nil or obj.status.observedGeneration < generation) then
  hs.message = "Waiting for the Coral operator to observe generation " .. tostring(generation)
  return hs
end
local ready = nil
local stalled = nil
for _, condition in ipairs(obj.status.conditions) do
  if condition.type == "Ready" then
    ready = condition
  elseif condition.type == "Stalled" then
    stalled = condition
  end
end
if stalled ~= nil and stalled.status == "True" then
  hs.status = "Degraded"
  hs.message = stalled.message or stalled.reason or "Stalled"
  return hs
end
local tree = obj.status.tree
if tree ~= nil and tree.rootStatus == "FAILURE" then
  hs.status = "Degraded"
  hs.message = "The behavior tree returned FAILURE"
  if tree.lastFailure ~= nil and tree.lastFailure.path ~= nil then
    hs.message = hs.message .. " at " .. tostring(tree.lastFailure.path)
  end
  return hs
end
local rollout = obj.status.rollout
if rollout ~= nil and rollout.rolledBack ~= nil then
  hs.status = "Degraded"
  hs.message = "Rolled back from revision " .. tostring(rollout.rolledBack.fromRevision) .. " to " ..
    tostring(rollout.rolledBack.toRevision) .. "; the spec's revision does not run"
  return hs
end
if ready ~= nil and ready.status == "True" then
  hs.status = "Healthy"
  hs.message = ready.message or "Ready"
  return hs
end
if rollout ~= nil and rollout.paused and not rollout.complete and rollout.failure == nil then
  hs.status = "Suspended"
  hs.message = rollout.message or "The rollout is paused"
  return hs
end
if ready ~= nil then
  hs.message = ready.message or ready.reason or hs.message
end
return hs
