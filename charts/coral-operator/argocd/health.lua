-- Argo CD health check for coral.dev CoralSystem and CoralInstance.
-- Healthy: Ready=True for the current generation. Degraded: Stalled=True (a bad tree or parameters,
-- a policy refusal, a failing component). Progressing: anything else, including a status the
-- operator has not written for the current generation yet.
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
if ready ~= nil and ready.status == "True" then
  hs.status = "Healthy"
  hs.message = ready.message or "Ready"
  return hs
end
if ready ~= nil then
  hs.message = ready.message or ready.reason or hs.message
end
return hs
