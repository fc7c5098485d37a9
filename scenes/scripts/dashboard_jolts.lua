-- The dashboard under the rubber toy jolts in each of its five directions in
-- turn (body impulses, no persistent forcing), letting the toy wobble between.
-- Usage: phasecast-console scenes/scripts/dashboard_jolts.lua
local toy = instances()[1].instance
for _, entry in ipairs(scenes()[1].palette) do
  local at = impulse(toy, entry)
  print(string.format("jolt %s at frame %d", entry, at))
  wait_frames(40, toy)
end
print("dashboard session done at frame " .. state(toy).frame)
