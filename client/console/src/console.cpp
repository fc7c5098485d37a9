// Lua bindings of the console. Every function is a thin call into the
// server's command socket (network.h); a server refusal or a transport
// failure becomes a Lua error with the server's message, positioned at the
// calling script line ("script.lua:12: impulse: server refused: ...").

#include "phasecast/client/console.h"

#include "console_lua.h"
#include "phasecast/client/network.h"

#include <fmt/format.h>
#include <google/protobuf/util/json_util.h>

#include <algorithm>
#include <atomic>
#include <map>
#include <thread>

namespace phasecast::client {
namespace {

std::atomic<bool> g_interrupted{false};

// Raises a Lua error carrying `message` at the caller's line. Declared
// [[noreturn]]: lua_error unwinds (a C++ exception with liblua5.4-c++).
[[noreturn]] int raise(lua_State* L, const std::string& message) {
  luaL_where(L, 1);
  lua_pushstring(L, message.c_str());
  lua_concat(L, 2);
  lua_error(L);
  std::abort();  // unreachable
}

}  // namespace

struct Console::Impl {
  // One instance's frame stream, kept between wait_frames calls.
  struct Stream {
    std::string endpoint;
    std::unique_ptr<FrameSubscriber> subscriber;
    SequenceTracker sequence;
  };

  ConsoleOptions options;
  CommandClient command;
  std::optional<v1::SceneList> scenes;  // cached: palettes do not change while a server runs...
  std::uint64_t scenes_connection = 0;  // ...so it is asked again only after a new connection
  std::map<std::uint32_t, Stream> streams;
  lua_State* L = nullptr;

  explicit Impl(ConsoleOptions o)
      : options(std::move(o)), command(options.endpoint, options.timeout, options.attempts, options.curve) {}

  const v1::SceneList& scene_list() {
    if (scenes && command.connections() != scenes_connection) recheck_scenes();
    if (!scenes) {
      scenes = command.list_scenes();
      scenes_connection = command.connections();
    }
    return *scenes;
  }

  // The connection to the server was made again (a restart?): ask for the
  // scenes again and say once if the server now serves other packages.
  void recheck_scenes() {
    const v1::SceneList before = *scenes;
    scenes = command.list_scenes();
    scenes_connection = command.connections();
    const std::string change = scene_change(before, *scenes);
    if (!change.empty()) {
      fmt::print(stderr, "phasecast-console: the server at {} came back with {}; scenes read again\n",
                 options.endpoint, change);
    }
  }

  // "", or what differs between two scene lists, e.g. "plate: hash 00ab.. -> 00cd..".
  static std::string scene_change(const v1::SceneList& before, const v1::SceneList& after) {
    std::string change;
    for (const auto& a : after.scenes()) {
      const auto b = std::find_if(before.scenes().begin(), before.scenes().end(),
                                  [&](const v1::SceneInfo& s) { return s.name() == a.name(); });
      if (b == before.scenes().end()) {
        change += fmt::format("{}new scene {}", change.empty() ? "" : ", ", a.name());
      } else if (b->content_hash() != a.content_hash()) {
        change += fmt::format("{}{}: hash {:016x} -> {:016x}", change.empty() ? "" : ", ", a.name(),
                              b->content_hash(), a.content_hash());
      }
    }
    if (after.scenes_size() < before.scenes_size() && change.empty()) change = "fewer scenes";
    return change.empty() ? change : "other packages (" + change + ")";
  }

  const v1::SceneInfo& scene(const std::string& name) {
    for (const auto& s : scene_list().scenes()) {
      if (s.name() == name) return s;
    }
    scenes.reset();  // the server may have been restarted with other packages
    for (const auto& s : scene_list().scenes()) {
      if (s.name() == name) return s;
    }
    throw NetworkError(fmt::format("no scene '{}' on the server", name));
  }

  v1::InstanceInfo instance(std::uint32_t id) {
    const v1::InstanceList list = command.list_instances();
    for (const auto& i : list.instances()) {
      if (i.instance() == id) return i;
    }
    throw NetworkError(fmt::format("no instance {} on the server", id));
  }

  // The frame stream of instance `id`, subscribed again when the server now
  // announces another frame endpoint.
  Stream& stream(std::uint32_t id) {
    const std::string pub = resolve_pub_endpoint(scene_list().pub_endpoint(), options.endpoint);
    auto& stream = streams[id];
    if (!stream.subscriber || stream.endpoint != pub) {
      stream.subscriber = std::make_unique<FrameSubscriber>(pub, id, options.curve);
      stream.endpoint = pub;
      stream.sequence = {};
    }
    return stream;
  }

  // Frames queued since the last wait are old: drop them, keeping the
  // sequence numbers, so that a restart is told from a stale queue.
  static void skip_queued(Stream& s) {
    while (auto f = s.subscriber->receive(std::chrono::milliseconds(0))) s.sequence.observe(f->seq());
  }

  // Waits until instance `id` has published `n` more frames; returns the
  // frame number reached. A restarted server numbers frames from 0 again:
  // the count then goes on from there instead of waiting for the old numbers.
  std::uint64_t wait_frames(std::uint32_t id, std::uint64_t n) {
    auto& s = stream(id);
    skip_queued(s);
    std::uint64_t target = instance(id).frame() + n;
    std::optional<std::uint64_t> last;
    auto silent_since = std::chrono::steady_clock::now();
    for (;;) {
      if (g_interrupted.exchange(false)) throw NetworkError("interrupted");
      auto f = s.subscriber->receive(std::chrono::milliseconds(20));
      if (s.subscriber->take_reconnected() && scenes) recheck_scenes();
      if (!f) {
        if (std::chrono::steady_clock::now() - silent_since > options.frame_timeout) {
          throw NetworkError(fmt::format("wait_frames: no frame of instance {} for {} ms{}", id,
                                         options.frame_timeout.count(), problem_suffix(*s.subscriber)));
        }
        continue;
      }
      silent_since = std::chrono::steady_clock::now();
      if (s.sequence.observe(f->seq())) {
        fmt::print(
            stderr,
            "phasecast-console: instance {}: frame numbers started again at {} (a restarted server?)\n", id,
            f->frame());
        target = f->frame() + (last && *last < target ? target - *last : n);
      }
      last = f->frame();
      if (f->frame() >= target) return f->frame();
    }
  }

  static std::string problem_suffix(FrameSubscriber& subscriber) {
    const std::string problem = subscriber.connection_problem();
    return problem.empty() ? std::string() : " (" + problem + ")";
  }
};

namespace {

Console::Impl& self(lua_State* L) {
  return *static_cast<Console::Impl*>(lua_touserdata(L, lua_upvalueindex(1)));
}

std::uint32_t instance_arg(lua_State* L, int index) {
  const lua_Integer id = luaL_checkinteger(L, index);
  if (id < 0 || id > 0xffffffff) luaL_argerror(L, index, "instance id out of range");
  return static_cast<std::uint32_t>(id);
}

void set_field(lua_State* L, const char* key, lua_Integer v) {
  lua_pushinteger(L, v);
  lua_setfield(L, -2, key);
}
void set_field(lua_State* L, const char* key, double v) {
  lua_pushnumber(L, v);
  lua_setfield(L, -2, key);
}
void set_field(lua_State* L, const char* key, bool v) {
  lua_pushboolean(L, v ? 1 : 0);
  lua_setfield(L, -2, key);
}
void set_field(lua_State* L, const char* key, const std::string& v) {
  lua_pushlstring(L, v.data(), v.size());
  lua_setfield(L, -2, key);
}

// Pushes {instance, scene, frame, entry, palette_index, irf, t, topic, allowed}.
void push_instance(lua_State* L, Console::Impl& c, const v1::InstanceInfo& i) {
  lua_createtable(L, 0, 9);
  set_field(L, "instance", static_cast<lua_Integer>(i.instance()));
  set_field(L, "scene", i.scene());
  set_field(L, "frame", static_cast<lua_Integer>(i.frame()));
  std::string entry = "rest";
  if (i.palette_index() >= 0) {
    const auto& palette = c.scene(i.scene()).palette();
    entry = i.palette_index() < palette.size() ? palette[i.palette_index()].name() : "?";
  }
  set_field(L, "entry", entry);
  set_field(L, "palette_index", static_cast<lua_Integer>(i.palette_index()));
  set_field(L, "irf", static_cast<lua_Integer>(i.irf()));
  set_field(L, "t", static_cast<lua_Integer>(i.irf_t()));
  set_field(L, "topic", i.topic());
  // The entry names the palette's rules allow next (a script can offer only those).
  const auto& palette = c.scene(i.scene()).palette();
  lua_createtable(L, i.allowed_now_size(), 0);
  lua_Integer n = 0;
  for (const auto d : i.allowed_now()) {
    if (static_cast<int>(d) >= palette.size()) continue;
    lua_pushlstring(L, palette[static_cast<int>(d)].name().data(),
                    palette[static_cast<int>(d)].name().size());
    lua_rawseti(L, -2, ++n);
  }
  lua_setfield(L, -2, "allowed");
}

// Wraps a binding body: C++ exceptions become Lua errors at the script line.
template <class F>
int guarded(lua_State* L, F&& body) {
  std::string error;
  try {
    return body(self(L));
  } catch (const std::exception& e) {
    error = e.what();
  }
  raise(L, error);
}

int l_scenes(lua_State* L) {
  return guarded(L, [L](Console::Impl& c) {
    c.scenes.reset();
    const auto& list = c.scene_list();
    lua_createtable(L, list.scenes_size(), 0);
    for (int i = 0; i < list.scenes_size(); ++i) {
      const auto& s = list.scenes(i);
      lua_createtable(L, 0, 9);
      set_field(L, "name", s.name());
      set_field(L, "package", s.package());
      set_field(L, "points", static_cast<lua_Integer>(s.points()));
      set_field(L, "triangles", static_cast<lua_Integer>(s.triangles()));
      set_field(L, "rank_u", static_cast<lua_Integer>(s.rank_u()));
      set_field(L, "rank_a", static_cast<lua_Integer>(s.rank_a()));
      set_field(L, "state_nodes", static_cast<lua_Integer>(s.state_nodes()));
      set_field(L, "dt", s.dt());
      lua_createtable(L, s.palette_size(), 0);
      for (int k = 0; k < s.palette_size(); ++k) {
        lua_pushstring(L, s.palette(k).name().c_str());
        lua_rawseti(L, -2, k + 1);
      }
      lua_setfield(L, -2, "palette");
      if (s.has_fidelity()) {
        const auto& f = s.fidelity();
        lua_createtable(L, 0, 6);
        set_field(L, "schedules", static_cast<lua_Integer>(f.schedules()));
        set_field(L, "median_nrmse", static_cast<double>(f.median_nrmse()));
        set_field(L, "p90_nrmse", static_cast<double>(f.p90_nrmse()));
        set_field(L, "moving", static_cast<lua_Integer>(f.moving()));
        set_field(L, "moving_within", static_cast<lua_Integer>(f.moving_within()));
        set_field(L, "adaptive", f.adaptive());
        lua_setfield(L, -2, "fidelity");
      }
      lua_rawseti(L, -2, i + 1);
    }
    return 1;
  });
}

int l_instances(lua_State* L) {
  return guarded(L, [L](Console::Impl& c) {
    const auto list = c.command.list_instances();
    lua_createtable(L, list.instances_size(), 0);
    for (int i = 0; i < list.instances_size(); ++i) {
      push_instance(L, c, list.instances(i));
      lua_rawseti(L, -2, i + 1);
    }
    return 1;
  });
}

int l_state(lua_State* L) {
  const std::uint32_t id = instance_arg(L, 1);
  return guarded(L, [L, id](Console::Impl& c) {
    push_instance(L, c, c.instance(id));
    return 1;
  });
}

int l_create(lua_State* L) {
  const std::string scene = luaL_checkstring(L, 1);
  return guarded(L, [L, scene](Console::Impl& c) {
    lua_pushinteger(L, c.command.create_instance(scene).instance());
    return 1;
  });
}

int l_destroy(lua_State* L) {
  const std::uint32_t id = instance_arg(L, 1);
  return guarded(L, [id](Console::Impl& c) {
    v1::Request r;
    r.mutable_destroy_instance()->set_instance(id);
    c.command.call(r, fmt::format("destroy({})", id));
    c.streams.erase(id);
    return 0;
  });
}

// impulse(id, entry [, at]) or impulse(id, entry, {at = frame}); entry is a
// palette name or a 0-based palette index. Returns the frame it lands in.
int l_impulse(lua_State* L) {
  const std::uint32_t id = instance_arg(L, 1);
  v1::Request r;
  auto* imp = r.mutable_impulse();
  imp->set_instance(id);
  std::string what;
  if (lua_type(L, 2) == LUA_TNUMBER) {
    const lua_Integer index = luaL_checkinteger(L, 2);
    if (index < 0) luaL_argerror(L, 2, "palette index must be >= 0");
    imp->set_index(static_cast<std::uint32_t>(index));
    what = fmt::format("impulse({}, {})", id, index);
  } else {
    imp->set_name(luaL_checkstring(L, 2));
    what = fmt::format("impulse({}, \"{}\")", id, imp->name());
  }
  if (lua_istable(L, 3)) {
    lua_getfield(L, 3, "at");
    lua_replace(L, 3);
  }
  if (!lua_isnoneornil(L, 3)) {
    const lua_Integer at = luaL_checkinteger(L, 3);
    if (at < 0) luaL_argerror(L, 3, "target frame must be >= 0");
    imp->set_at_frame(static_cast<std::uint64_t>(at));
  }
  return guarded(L, [L, &r, &what](Console::Impl& c) {
    lua_pushinteger(L, static_cast<lua_Integer>(c.command.call(r, what).impulse().at_frame()));
    return 1;
  });
}

void sleep_interruptibly(lua_State* L, std::chrono::duration<double> duration) {
  const auto end = std::chrono::steady_clock::now() + duration;
  while (std::chrono::steady_clock::now() < end) {
    if (g_interrupted.exchange(false)) raise(L, "interrupted");
    std::this_thread::sleep_for(std::min<std::chrono::duration<double>>(
        std::chrono::milliseconds(10), end - std::chrono::steady_clock::now()));
  }
}

int l_wait(lua_State* L) {
  const double seconds = luaL_checknumber(L, 1);
  if (!(seconds >= 0)) luaL_argerror(L, 1, "seconds must be >= 0");
  sleep_interruptibly(L, std::chrono::duration<double>(seconds));
  return 0;
}

// wait_frames(n [, id]): until instance id (default: the first one) has
// published n more frames. Returns the frame number reached.
int l_wait_frames(lua_State* L) {
  const lua_Integer n = luaL_checkinteger(L, 1);
  if (n < 0) luaL_argerror(L, 1, "frame count must be >= 0");
  const bool has_id = !lua_isnoneornil(L, 2);
  const std::uint32_t given = has_id ? instance_arg(L, 2) : 0;
  return guarded(L, [L, n, has_id, given](Console::Impl& c) {
    std::uint32_t id = given;
    if (!has_id) {
      const auto list = c.command.list_instances();
      if (list.instances_size() == 0) throw NetworkError("wait_frames: the server has no instance");
      id = list.instances(0).instance();
    }
    lua_pushinteger(L, static_cast<lua_Integer>(c.wait_frames(id, static_cast<std::uint64_t>(n))));
    return 1;
  });
}

int l_record(lua_State* L) {
  const std::string path = luaL_checkstring(L, 1);
  return guarded(L, [L, path](Console::Impl& c) {
    v1::Request r;
    r.mutable_record_start()->set_path(path);
    const auto reply = c.command.call(r, fmt::format("record(\"{}\")", path));
    lua_pushstring(L, reply.record().path().c_str());
    return 1;
  });
}

int l_stop_record(lua_State* L) {
  return guarded(L, [L](Console::Impl& c) {
    v1::Request r;
    r.mutable_record_stop();
    const auto reply = c.command.call(r, "stop_record()");
    lua_pushinteger(L, static_cast<lua_Integer>(reply.record().frames_written()));
    return 1;
  });
}

int l_stats(lua_State* L) {
  return guarded(L, [L](Console::Impl& c) {
    v1::Request r;
    r.mutable_stats();
    const auto s = c.command.call(r, "stats()").stats();
    lua_createtable(L, 0, 12);
    set_field(L, "ticks", static_cast<lua_Integer>(s.ticks()));
    set_field(L, "frames_published", static_cast<lua_Integer>(s.frames_published()));
    set_field(L, "late_ticks", static_cast<lua_Integer>(s.late_ticks()));
    set_field(L, "rate_hz", s.rate_hz());
    set_field(L, "requests", static_cast<lua_Integer>(s.requests()));
    set_field(L, "bad_requests", static_cast<lua_Integer>(s.bad_requests()));
    set_field(L, "impulses_applied", static_cast<lua_Integer>(s.impulses_applied()));
    set_field(L, "impulses_refused", static_cast<lua_Integer>(s.impulses_refused()));
    set_field(L, "max_tick_seconds", s.max_tick_seconds());
    set_field(L, "recording", s.recording());
    set_field(L, "recording_error", s.recording_error());
    lua_createtable(L, s.instances_size(), 0);
    for (int i = 0; i < s.instances_size(); ++i) {
      push_instance(L, c, s.instances(i));
      lua_rawseti(L, -2, i + 1);
    }
    lua_setfield(L, -2, "instances");
    return 1;
  });
}

int l_help(lua_State* L) {
  fmt::print("{}", console_help_text());
  (void)L;
  return 0;
}

const luaL_Reg kFunctions[] = {{"scenes", l_scenes},   {"instances", l_instances},
                               {"state", l_state},     {"create", l_create},
                               {"destroy", l_destroy}, {"impulse", l_impulse},
                               {"wait", l_wait},       {"wait_frames", l_wait_frames},
                               {"record", l_record},   {"stop_record", l_stop_record},
                               {"stats", l_stats},     {"help", l_help},
                               {nullptr, nullptr}};

}  // namespace

Console::Console(ConsoleOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {
  impl_->L = luaL_newstate();
  if (!impl_->L) throw std::runtime_error("cannot create a Lua state (out of memory)");
  luaL_openlibs(impl_->L);
  lua_pushglobaltable(impl_->L);
  lua_pushlightuserdata(impl_->L, impl_.get());
  luaL_setfuncs(impl_->L, kFunctions, 1);
  lua_pop(impl_->L, 1);
  run_string(console_prelude(), "=prelude");
}

Console::~Console() {
  if (impl_->L) lua_close(impl_->L);
}

void Console::interrupt() {
  g_interrupted = true;
}

void clear_interrupt() {
  g_interrupted = false;
}

void Console::run_file(const std::filesystem::path& script) {
  lua_State* L = impl_->L;
  if (luaL_loadfile(L, script.c_str()) != LUA_OK) {
    std::string message = lua_tostring(L, -1);
    lua_pop(L, 1);
    throw ScriptError(message);
  }
  run_loaded(L);
}

void Console::run_string(const std::string& code, const std::string& chunk_name) {
  lua_State* L = impl_->L;
  if (luaL_loadbuffer(L, code.data(), code.size(), chunk_name.c_str()) != LUA_OK) {
    std::string message = lua_tostring(L, -1);
    lua_pop(L, 1);
    throw ScriptError(message);
  }
  run_loaded(L);
}

void Console::repl() {
  run_repl(impl_->L);
}

std::string Console::server_stats_json() {
  v1::Request r;
  r.mutable_stats();
  const auto stats = impl_->command.call(r, "stats").stats();
  google::protobuf::util::JsonPrintOptions options;
  options.preserve_proto_field_names = true;
  options.add_whitespace = true;
  std::string json;
  if (const auto status = google::protobuf::util::MessageToJsonString(stats, &json, options); !status.ok())
    throw std::runtime_error(fmt::format("stats: cannot write JSON: {}", status.ToString()));
  return json;
}

}  // namespace phasecast::client
