-- The plant's pot is pushed right and left, stopping in between, PUSHES times
-- (default 3): each push is a velocity discontinuity of the palette (§3.3).
-- Usage: phasecast-console scenes/scripts/pot_left_right.lua
local pot = instances()[1].instance
local pushes = tonumber(os.getenv("PUSHES") or "3")
for i = 1, pushes do
  for _, entry in ipairs({"right", "stop", "left", "stop"}) do
    local at = impulse(pot, entry)
    print(string.format("push %d: %s at frame %d", i, entry, at))
    wait_frames(30, pot)
  end
end
print("pot session done at frame " .. state(pot).frame)
