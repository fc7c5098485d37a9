-- The plant's pot is pushed right and left, stopping in between, PUSHES times
-- (default 3): each push is a velocity discontinuity of the palette (§3.3).
-- Usage: phasecast-console scenes/scripts/pot_left_right.lua
local pot = instances()[1].instance

-- A push stops by itself at the end of the pot's range (its IRFs end in
-- "stop"): ask for "stop" only while the pot still moves.
local function stop(id)
  if state(id).entry ~= "stop" then return impulse(id, "stop") end
  return state(id).frame
end
local pushes = tonumber(os.getenv("PUSHES") or "3")
for i = 1, pushes do
  for _, entry in ipairs({"right", "stop", "left", "stop"}) do
    local at = entry == "stop" and stop(pot) or impulse(pot, entry)
    print(string.format("push %d: %s at frame %d", i, entry, at))
    wait_frames(30, pot)
  end
end
print("pot session done at frame " .. state(pot).frame)
