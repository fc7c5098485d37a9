-- Gusts across a field of plants (scenes/fields/plant_field.toml): every pot
-- is pushed, column after column from the left, then stopped in the same
-- order, so the leaves swing as a wave crossing the field (§3.3: each push
-- is an impulse of the palette, each plant plays its own IRFs). Gusts push
-- right and left in turn, so the pots stay within their range.
-- The columns are the renderer's default grid: instance k (k-th in id order,
-- from 0) stands in column k mod ceil(sqrt(n)).
-- Usage: phasecast-console --connect tcp://host:5555 scenes/scripts/field_gust.lua
local ids = {}
for _, s in ipairs(instances()) do ids[#ids + 1] = s.instance end
table.sort(ids)
local columns = math.ceil(math.sqrt(#ids))
local GAP = tonumber(os.getenv("GUST_GAP") or "6")  -- frames between neighbouring columns

local function column_of(c)
  local out = {}
  for k, id in ipairs(ids) do
    if (k - 1) % columns == c then out[#out + 1] = id end
  end
  return out
end

-- A push stops by itself at the end of the pot's range (its IRFs end in
-- "stop"): a refusal there is counted, not an error.
local refused = 0
local function try(id, entry)
  if entry == "stop" and state(id).entry == "stop" then return end
  if not pcall(impulse, id, entry) then refused = refused + 1 end
end

local gusts = tonumber(os.getenv("GUSTS") or "2")
for g = 1, gusts do
  local push = g % 2 == 1 and "right" or "left"
  for _, entry in ipairs({push, "stop"}) do
    for c = 0, columns - 1 do
      for _, id in ipairs(column_of(c)) do try(id, entry) end
      wait_frames(GAP, ids[1])
    end
    print(string.format("gust %d: %s crossed %d columns of %d plants", g, entry, columns, #ids))
    wait_frames(entry == "stop" and 40 or 8, ids[1])
  end
end
if refused > 0 then print(refused .. " impulses refused (a pot at the end of its range)") end
print("field session done at frame " .. state(ids[1]).frame)
