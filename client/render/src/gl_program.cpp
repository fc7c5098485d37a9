#include "gl_program.h"

#include "phasecast/client/embedded_shaders.h"
#include "phasecast/client/low_rank_renderer.h"

#include <fmt/format.h>

#include <array>

namespace phasecast::client::detail {
namespace {

// The first line of a GL info log: enough for a one-line error.
std::string first_line(const std::array<char, 4096>& log) {
  const std::string text(log.data());
  return text.substr(0, text.find('\n'));
}

Shader compile(const GlFunctions& gl, GLenum stage, std::string_view source, const char* name) {
  Shader shader(gl, stage);
  const char* text = source.data();
  const auto length = static_cast<GLint>(source.size());
  gl.glShaderSource(shader.get(), 1, &text, &length);
  gl.glCompileShader(shader.get());
  GLint ok = GL_FALSE;
  gl.glGetShaderiv(shader.get(), GL_COMPILE_STATUS, &ok);
  if (!ok) {
    std::array<char, 4096> log{};
    gl.glGetShaderInfoLog(shader.get(), static_cast<GLsizei>(log.size()), nullptr, log.data());
    throw RenderError(fmt::format("shader {} does not compile: {}", name, first_line(log)));
  }
  return shader;
}

void check_link(const GlFunctions& gl, const Program& program, const char* name) {
  GLint ok = GL_FALSE;
  gl.glGetProgramiv(program.get(), GL_LINK_STATUS, &ok);
  if (!ok) {
    std::array<char, 4096> log{};
    gl.glGetProgramInfoLog(program.get(), static_cast<GLsizei>(log.size()), nullptr, log.data());
    throw RenderError(fmt::format("shader program {} does not link: {}", name, first_line(log)));
  }
}

Program attach_and_link(const GlFunctions& gl, std::initializer_list<const Shader*> shaders, const char* name,
                        bool capture = false) {
  Program program(gl);
  for (const Shader* s : shaders) gl.glAttachShader(program.get(), s->get());
  if (capture) {
    const char* varyings[] = {"world_position", "radiance"};
    gl.glTransformFeedbackVaryings(program.get(), 2, varyings, GL_INTERLEAVED_ATTRIBS);
  }
  gl.glLinkProgram(program.get());
  check_link(gl, program, name);
  return program;
}

}  // namespace

GLint GlProgram::uniform(const char* name) const {
  const auto it = locations_.find(std::string_view(name));
  if (it != locations_.end()) return it->second;
  const GLint location = gl_->glGetUniformLocation(program_.get(), name);
  locations_.emplace(name, location);
  return location;
}

// The shaders are freed on return: a linked program no longer needs them.
GlProgram link_vertex_program(const GlFunctions& gl, std::string_view vertex, const char* vertex_name,
                              bool capture) {
  const Shader vs = compile(gl, GL_VERTEX_SHADER, vertex, vertex_name);
  const Shader fs = compile(gl, GL_FRAGMENT_SHADER, shaders::radiance_frag, "radiance.frag");
  return GlProgram(gl, attach_and_link(gl, {&vs, &fs}, vertex_name, capture));
}

GlProgram link_program(const GlFunctions& gl, std::string_view vertex, const char* vertex_name,
                       std::string_view fragment, const char* fragment_name) {
  const Shader vs = compile(gl, GL_VERTEX_SHADER, vertex, vertex_name);
  const Shader fs = compile(gl, GL_FRAGMENT_SHADER, fragment, fragment_name);
  return GlProgram(gl, attach_and_link(gl, {&vs, &fs}, vertex_name));
}

GlProgram link_compute_program(const GlFunctions& gl, std::string_view source, const char* name) {
  const Shader cs = compile(gl, GL_COMPUTE_SHADER, source, name);
  return GlProgram(gl, attach_and_link(gl, {&cs}, name));
}

}  // namespace phasecast::client::detail
