#pragma once
// Private pieces of the console: running a loaded chunk with a traceback-free
// one-line error, the Lua prelude, the help text and the terminal REPL.

#include <lua.hpp>

namespace phasecast::client {

// Calls the chunk on top of the stack; throws ScriptError("chunk:line: message").
void run_loaded(lua_State* L);

// Lua source run at start: show() pretty-prints values (the REPL uses it).
const char* console_prelude();

const char* console_help_text();

// Forgets a Ctrl-C that arrived while no wait was running (e.g. at the prompt).
void clear_interrupt();

// Read-eval-print loop with readline line editing and history.
void run_repl(lua_State* L);

}  // namespace phasecast::client
