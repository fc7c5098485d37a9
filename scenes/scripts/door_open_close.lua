-- The cloth door swings open and shut, three times: each swing is an impulse
-- of the palette (open / stop / close), timed in frames so that the session
-- replays exactly. Usage: phasecast-console scenes/scripts/door_open_close.lua
local door = instances()[1].instance

-- The door stops by itself at the end of its range (its IRFs end in "stop"):
-- ask for "stop" only while it still moves.
local function stop(id)
  if state(id).entry ~= "stop" then impulse(id, "stop") end
end
local swings = tonumber(os.getenv("SWINGS") or "3")
for i = 1, swings do
  local at = impulse(door, "open")
  print(string.format("swing %d: open at frame %d", i, at))
  wait_frames(45, door)
  stop(door)
  wait_frames(60, door)
  impulse(door, "close")
  wait_frames(45, door)
  stop(door)
  wait_frames(60, door)
end
print("door session done at frame " .. state(door).frame)
