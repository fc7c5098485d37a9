#pragma once
// A linked GL program and the locations of its uniforms, each looked up once
// (the first time it is set) rather than by name every frame; and the linking
// of the client's programs from their embedded GLSL (shaders/).

#include "gl_handles.h"

#include <map>
#include <string>
#include <string_view>

namespace phasecast::client::detail {

class GlProgram {
 public:
  GlProgram() = default;
  GlProgram(const GlFunctions& gl, Program program) : gl_(&gl), program_(std::move(program)) {}

  GLuint get() const { return program_.get(); }
  explicit operator bool() const { return static_cast<bool>(program_); }
  // glUseProgram.
  void use() const { gl_->glUseProgram(program_.get()); }
  // The uniform's location (-1 when the program has none of that name, which
  // GL's glUniform* ignore).
  GLint uniform(const char* name) const;

 private:
  const GlFunctions* gl_ = nullptr;
  Program program_;
  mutable std::map<std::string, GLint, std::less<>> locations_;
};

// A vertex program with radiance.frag; `capture`: record world_position and
// radiance by transform feedback. Throws RenderError naming the shader whose
// compile or link failed, with the first line of GL's log.
GlProgram link_vertex_program(const GlFunctions& gl, std::string_view vertex, const char* vertex_name,
                              bool capture);

// A vertex and a fragment shader of their own.
GlProgram link_program(const GlFunctions& gl, std::string_view vertex, const char* vertex_name,
                       std::string_view fragment, const char* fragment_name);

// One compute shader.
GlProgram link_compute_program(const GlFunctions& gl, std::string_view source, const char* name);

}  // namespace phasecast::client::detail
