#include "console_lua.h"
#include "phasecast/client/console.h"

#include <fmt/format.h>
#include <readline/history.h>
#include <readline/readline.h>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace phasecast::client {

void run_loaded(lua_State* L) {
  if (lua_pcall(L, 0, LUA_MULTRET, 0) != LUA_OK) {
    std::string message = lua_isstring(L, -1) ? lua_tostring(L, -1) : "error object is not a string";
    lua_pop(L, 1);
    throw ScriptError(message);
  }
}

const char* console_prelude() {
  return R"lua(
-- show(v): prints a value, tables one entry per line in key order.
local function render(v, indent)
  if type(v) ~= "table" then
    return type(v) == "string" and string.format("%q", v) or tostring(v)
  end
  local keys = {}
  for k in pairs(v) do keys[#keys + 1] = k end
  table.sort(keys, function(a, b)
    if type(a) == type(b) then return a < b end
    return type(a) == "number"
  end)
  if #keys == 0 then return "{}" end
  local lines = {}
  for _, k in ipairs(keys) do
    local key = type(k) == "number" and ("[" .. k .. "]") or k
    lines[#lines + 1] = indent .. "  " .. key .. " = " .. render(v[k], indent .. "  ")
  end
  return "{\n" .. table.concat(lines, ",\n") .. "\n" .. indent .. "}"
end
function show(...)
  local n = select("#", ...)
  for i = 1, n do print(render((select(i, ...)), "")) end
end
)lua";
}

const char* console_help_text() {
  return R"(Phasecast console: Lua 5.4 with these functions (docs/console.md):
  scenes()                       scenes on the server: name, palette, ranks, sizes
  instances()                    every instance: instance, scene, frame, entry, irf, t
  state(id)                      one instance: entry ("rest" or a palette name), irf, t, frame
  create(scene) -> id            a new instance of scene, at rest
  destroy(id)
  impulse(id, entry [, at])      palette entry by name or 0-based index, in frame `at`
                                 (or the next tick); returns the frame it lands in
  wait(seconds)                  sleep (Ctrl-C cancels)
  wait_frames(n [, id])          until instance id (default: the first) published n more frames
  record(path) / stop_record()   write the published stream to a file on the server
  stats()                        ticks, frames, late ticks, requests, impulses, longest tick
  show(value)                    pretty-print tables
  help()                         this text
)";
}

namespace {

std::filesystem::path history_file() {
  const char* home = std::getenv("HOME");
  return home ? std::filesystem::path(home) / ".phasecast_console_history" : std::filesystem::path();
}

// Evaluates one line: as an expression first (its values are shown), else as a statement.
void evaluate(lua_State* L, const std::string& line) {
  const std::string expression = "return " + line;
  if (luaL_loadbuffer(L, expression.data(), expression.size(), "=stdin") != LUA_OK) {
    lua_pop(L, 1);
    if (luaL_loadbuffer(L, line.data(), line.size(), "=stdin") != LUA_OK) {
      std::string message = lua_tostring(L, -1);
      lua_pop(L, 1);
      throw ScriptError(message);
    }
  }
  const int base = lua_gettop(L) - 1;
  run_loaded(L);
  const int results = lua_gettop(L) - base;
  if (results > 0) {
    lua_getglobal(L, "show");
    lua_insert(L, base + 1);
    if (lua_pcall(L, results, 0, 0) != LUA_OK) lua_pop(L, 1);
  }
}

}  // namespace

void run_repl(lua_State* L) {
  const auto history = history_file();
  if (!history.empty()) read_history(history.c_str());
  fmt::print("Phasecast console (Lua 5.4). help() lists the functions; Ctrl-D quits.\n");
  while (char* raw = readline("phasecast> ")) {
    const std::string line(raw);
    std::free(raw);
    if (line.find_first_not_of(" \t") == std::string::npos) continue;
    add_history(line.c_str());
    clear_interrupt();
    try {
      evaluate(L, line);
    } catch (const ScriptError& e) {
      fmt::print(stderr, "{}\n", e.what());
    }
  }
  fmt::print("\n");
  if (!history.empty()) write_history(history.c_str());
}

}  // namespace phasecast::client
